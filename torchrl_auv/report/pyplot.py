"""matplotlib's pyplot for the report's figures, on the non-interactive Agg backend (files, no
screen), with a clear error where matplotlib is not installed (the ``recipes`` extra).

Examples:
    >>> plt = pyplot()
    >>> plt.get_backend().lower()
    'agg'
"""

from __future__ import annotations

__all__ = ["pyplot"]


def pyplot():
    """``matplotlib.pyplot`` with the Agg backend; ``ImportError`` naming the extra without it."""
    try:
        import matplotlib
    except ImportError as error:
        raise ImportError(
            "the report's figures need matplotlib, which the core package does not: "
            "pip install 'torchrl-auv[recipes]'"
        ) from error
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt
