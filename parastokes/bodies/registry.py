"""The import path of the body registry before the folders became layers: the same module as
:mod:`parastokes.registry.kinds`, so a body written against the older documentation runs
unchanged."""

import sys

from ..registry import kinds as _module

sys.modules[__name__] = _module
