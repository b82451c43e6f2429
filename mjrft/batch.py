"""``mjrft.batch`` is the public name of :mod:`mjrft.field.batch`.

Many copies of one granular scene on MuJoCo's threaded batch.
The name stays stable for outside scripts while the implementation lives in its layer; importing
it yields that very module (one implementation, no copies of its names).
"""

import sys

from mjrft.field.batch import __name__ as _implementation

sys.modules[__name__] = sys.modules[_implementation]
