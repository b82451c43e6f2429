"""``mjrft.geometry`` is the public name of :mod:`mjrft.core.geometry`.

Surface elements of primitives and checked meshes.
The name stays stable for outside scripts while the implementation lives in its layer; importing
it yields that very module (one implementation, no copies of its names).
"""

import sys

from mjrft.core.geometry import __name__ as _implementation

sys.modules[__name__] = sys.modules[_implementation]
