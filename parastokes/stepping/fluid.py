"""The import path of the compiled fluid parts before the folders became layers: the same module as
:mod:`parastokes.fluid.compiled`, so a body written against the older documentation runs
unchanged."""

import sys

from ..fluid import compiled as _module

sys.modules[__name__] = _module
