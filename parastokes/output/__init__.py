"""What a run leaves behind, and the tools that read it back.

- :mod:`.rundir`: claiming a run directory (lock, no silent overwrite, atomic result);
- :mod:`.trajectory`: the HDF5 trajectory and its XDMF description;
- :mod:`.figures`: figure files (formats, atomic writes);
- :mod:`.plots`: the figures of a run (η^k, positions, speedups);
- :mod:`.gantt`: the Gantt chart of a Parareal schedule.
"""
