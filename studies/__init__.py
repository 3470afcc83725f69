"""The studies: the solver-accuracy study and the population study, with their harnesses and commands.

They import the product (rig); the product never imports them (an import contract says so). The
`rig-study` command (`python -m studies`) runs them; benchmarks/ times and documents them.
"""
