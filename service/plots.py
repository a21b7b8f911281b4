"""matplotlib, imported only when a figure is drawn (``--plot``, study figures, the condition
report's plots).

matplotlib is a core dependency since the condition report (service/reports/), which the API
serves; the ``plots`` extra still names it for old install commands. In an environment that
lacks it anyway, asking for a figure is a sentence that says how to install it, raised before
any long computation starts.
"""

from __future__ import annotations

import importlib.util

from service.errors import UserError

INSTALL_HINT = "pip install 'hvcb[plots]'"


def require_matplotlib(what: str = "figures") -> None:
    """Raise ``UserError`` naming the install command unless matplotlib is importable."""
    if importlib.util.find_spec("matplotlib") is None:
        raise UserError(f"{what} need matplotlib, which is not installed: {INSTALL_HINT}")


def pyplot(what: str = "figures"):
    """``matplotlib.pyplot`` on the non-interactive Agg backend (safe in workers and on servers)."""
    require_matplotlib(what)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
