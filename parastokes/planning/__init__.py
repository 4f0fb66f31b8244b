"""``parastokes plan``: the fastest route to a simulation's end (docs/planning.md).

- :mod:`.baseline`: the fastest serial run of a given accuracy, by a bounded search, cached
  beside the configuration;
- :mod:`.routes`: the predicted wall time of each route (serial, spatial, Parareal in either
  schedule, both combined) from measured costs;
- :mod:`.command`: the command itself (choose F, tune the coarse solver, compare, write
  PLAN.toml and PLAN.json).
"""
