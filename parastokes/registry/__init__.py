"""The registries: how the rest of the package finds a plug-in by name or by type, one module each.

- :mod:`.kinds`: body kinds (``kind = "rod"``, ``"package.module:Name"``, entry points);
- :mod:`.loops`: compiled loops of steps, compiled scene data and GPU device parts, by exact type;
- :mod:`.coarse`: coarse-solver families (``[coarse] kind``).

They sit in one low layer so that a body, a loop or a family registers itself without the
registry importing it, and the layers that ask (config, run, output) import only this folder.
"""
