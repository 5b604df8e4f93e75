"""Figures of the downstream checks written as PNG files, each atomically."""

from __future__ import annotations

from pathlib import Path


def save_figure(fig, path) -> bool:
    """Lay out a matplotlib figure, write it as a PNG atomically and close it. **Returns:** True."""
    import matplotlib.pyplot as plt

    from g2r_jax.io.atomic import atomic_write_bytes

    fig.tight_layout()
    try:
        atomic_write_bytes(Path(path), lambda handle: fig.savefig(handle, format="png", dpi=90))
    finally:
        plt.close(fig)
    return True
