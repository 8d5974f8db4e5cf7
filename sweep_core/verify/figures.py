"""Figures and files of the verification report, all written through
:mod:`sweep_core.io.outputs` (a finished file or none)."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from sweep_core.io.outputs import replacing


def figure(width: float = 6.4, height: float = 4.4) -> tuple[Any, Any]:
    """A matplotlib figure and axes on the Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(width, height))
    return fig, ax


def save(fig: Any, path: Path) -> Path:
    """Writes the figure as PNG at ``path`` and closes it."""
    import matplotlib.pyplot as plt

    with replacing(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110, bbox_inches="tight")
    plt.close(fig)
    return Path(os.fspath(path))


def walls(ax: Any, spec: dict) -> None:
    """Draws a scene spec's segment and polyline walls in black."""
    for w in spec.get("walls", []):
        if w.get("kind") == "segment":
            pts = [w["a"], w["b"]]
        elif w.get("kind") == "polyline":
            pts = list(w["points"]) + ([w["points"][0]] if w.get("closed") else [])
        else:
            continue
        ax.plot([p[0] for p in pts], [p[1] for p in pts], color="black", lw=1.5)
