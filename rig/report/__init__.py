"""Reports and plots: thin clients of the results the rest of the controller computes."""
