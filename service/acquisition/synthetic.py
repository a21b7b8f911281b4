"""Moved to :mod:`drivers.synthetic` (below both the emulators and acquisition; docs/architecture.md).

The old name is the same module object, kept so that code written against it still imports;
new code imports ``drivers.synthetic``.
"""

import sys

from drivers import synthetic as _moved

sys.modules[__name__] = _moved
