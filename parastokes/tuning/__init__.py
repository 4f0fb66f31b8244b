"""Automatic design of the coarse solver (``parastokes tune``, docs/tuning.md).

- :mod:`.space`: the candidates (scheme, Lagrange nodes, Richardson, coarse grid, step);
- :mod:`.stability`: step limits, the derived margin, ρ(DG) of the combined slice map;
- :mod:`.slice_map`: ρ(DG) and ‖DG‖ of a slice map from finite differences (ARPACK, dense);
- :mod:`.pilot`: the pilot window with the fine reference, η^k measured by Algorithm 1;
- :mod:`.cost`: N_it for η*, γ_G/γ_F on ``cores``, the speedup of eq. 14;
- :mod:`.report`: TUNED.json, TUNED.toml, the table and the figure;
- :mod:`.search`: :func:`tune`, the search itself.
"""

from .search import Candidate, Progress, TuneResult, tune
from .space import Settings, Space, TuningError, parse_space

__all__ = ["Candidate", "Progress", "Settings", "Space", "TuneResult", "TuningError",
           "parse_space", "tune"]
