"""Checks of a calibration adapter's exact Jacobian the fit tests share."""

from __future__ import annotations

import numpy as np


def central_difference(adapter, theta, rows, j: int, quantity: str) -> np.ndarray:
    """d ``quantity`` ("tip" or "markers" of the adapter's predictions at ``rows``) / d
    theta_j by central differences of whole predictions, relative step 1e-5 (truncation
    ~1e-10 of the derivative)."""
    h = 1e-5 * theta[j]
    up, down = np.array(theta, dtype=float), np.array(theta, dtype=float)
    up[j] += h
    down[j] -= h
    high = getattr(adapter.predict(up, rows, False), quantity)
    low = getattr(adapter.predict(down, rows, False), quantity)
    return (high - low) / (2 * h)
