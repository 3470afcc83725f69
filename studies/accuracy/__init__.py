"""The solver-accuracy study: work-precision sweeps, the efficiency curve's cost, plots, a stopwatch."""
