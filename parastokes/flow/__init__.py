"""The fluid itself: velocity fields, streamlines and movies of any run (docs/tutorial.md, "From a
run to its flow").

- :mod:`.evaluate`: :func:`velocity` of any system or scene at any points (eq. 6 with images and
  u∞), through the compiled kernels;
- :mod:`.average`: :func:`time_average` over a window of saved frames;
- :mod:`.streamlines`: :func:`streamlines` of a frame in 3-D from seed points;
- :mod:`.grids`: planes and boxes of points, and how the command line names them;
- :mod:`.xdmf`: a structured grid as HDF5 + XDMF (ParaView opens it as is);
- :mod:`.render`: speed, streamlines and bodies in a plane (PNG);
- :mod:`.run`: a finished run's system and full states rebuilt from its directory;
- :mod:`.fields`: a run's flow on a grid (shared by the commands); :mod:`.movie`: MP4/GIF;
- :mod:`.command`: ``parastokes flow`` and ``parastokes movie``.

This package sits at the output layer (beside :mod:`parastokes.output.trajectory` and
:mod:`parastokes.output.plots`): nothing below it imports it.
"""

from .average import time_average
from .evaluate import velocity
from .grids import Grid
from .run import load_run
from .streamlines import streamlines
from .xdmf import read_grid, write_grid

__all__ = ["Grid", "load_run", "read_grid", "streamlines", "time_average", "velocity",
           "write_grid"]
