"""The import path of the coarse-solver registry before the folders became layers: the same module
as :mod:`parastokes.registry.coarse`, so a body written against the older documentation runs
unchanged."""

import sys

from ..registry import coarse as _module

sys.modules[__name__] = _module
