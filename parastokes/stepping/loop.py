"""The import path of the compiled loop of steps before the folders became layers: the same module
as :mod:`parastokes.integrate.loop`, so a body written against the older documentation runs
unchanged."""

import sys

from ..integrate import loop as _module

sys.modules[__name__] = _module
