"""Moved to :mod:`drivers.stream_script` (below both the emulators and acquisition; docs/architecture.md).

The old name is the same module object, kept so that code written against it still imports;
new code imports ``drivers.stream_script``.
"""

import sys

from drivers import stream_script as _moved

sys.modules[__name__] = _moved
