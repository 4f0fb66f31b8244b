"""The import path of the registry of compiled loops before the folders became layers: the same
module as :mod:`parastokes.registry.loops`, so a body written against the older documentation runs
unchanged."""

import sys

from ..registry import loops as _module

sys.modules[__name__] = _module
