"""Experiment sweeps as in the paper: environments x demo counts x seeds x approaches.

A sweep is a graph of small work units (cells): ``demos(env, seed)`` ->
``skills(env, count, seed)`` -> ``eval(env, count, seed, approach)`` (an approach that
plans with the environment's own skills has one eval cell per (env, seed)). Each finished
cell is stored as its own JSON file, so a sweep resumes where it stopped; the table and
the figures are computed from the stored cells.

Modules: :mod:`presets` (what to sweep), :mod:`cells` (the cell graph), :mod:`work` (what
a worker does for one cell), :mod:`store` (cell files), :mod:`backends` (process pool or
Ray), :mod:`sweep` (scheduling), :mod:`aggregate` (mean +- std table), :mod:`plots`
(figures); the command is :mod:`bpns.cli.experiment`.
"""
