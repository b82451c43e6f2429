"""``mjrft.simulate`` is the public name of :mod:`mjrft.app.simulate`.

Runs of an MJCF scene with the field installed.
The name stays stable for outside scripts while the implementation lives in its layer; importing
it yields that very module (one implementation, no copies of its names).
"""

import sys

from mjrft.app.simulate import __name__ as _implementation

sys.modules[__name__] = sys.modules[_implementation]
