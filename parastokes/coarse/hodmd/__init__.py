"""The HODMD-Parareal coarse-solver family (``[coarse] kind = "hodmd"``; Liu, arXiv 2503.03109).

:mod:`.dmd`: the HODMD function; :mod:`.solver`: the coarse solver (traces and corrections);
:mod:`.family`: its config section.
"""
