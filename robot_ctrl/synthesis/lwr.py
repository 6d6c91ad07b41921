"""Locally weighted linear regression (thesis 3.4.2, after Atkeson et al.).

For a query ``x`` the training inputs ``x_i`` get Gaussian weights
``w_i = exp(−½ ‖(x − x_i) / h‖²)`` (``h`` per input dimension: bandwidth × the input's standard
deviation), and the prediction is the weighted least-squares affine fit ``y ≈ β₀ + βᵀ(x − x̄)``
evaluated at ``x``, with a small ridge on the slopes so sparse neighbourhoods stay well posed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LocallyWeightedRegression:
    inputs: np.ndarray  # (n, d)
    outputs: np.ndarray  # (n, p)
    scale: np.ndarray  # (d,) kernel width per input [input units]
    ridge: float = 1e-6

    @classmethod
    def fit(cls, inputs: np.ndarray, outputs: np.ndarray, bandwidth: float = 0.5) -> "LocallyWeightedRegression":
        inputs = np.atleast_2d(np.asarray(inputs, dtype=float).T).T
        outputs = np.asarray(outputs, dtype=float).reshape(len(inputs), -1)
        spread = inputs.std(axis=0)
        return cls(inputs, outputs, bandwidth * np.where(spread > 0, spread, 1.0))

    def __call__(self, x) -> np.ndarray:
        """Prediction (p,) at one query point (d,)."""
        d = (self.inputs - np.atleast_1d(np.asarray(x, dtype=float))) / self.scale
        w = np.exp(-0.5 * np.sum(d**2, axis=1))
        A = np.hstack([np.ones((len(d), 1)), d])
        sw = np.sqrt(w)[:, None]
        reg = self.ridge * np.diag([0.0] + [1.0] * d.shape[1]) * w.sum()
        beta = np.linalg.solve((A * sw).T @ (A * sw) + reg, (A * sw).T @ (self.outputs * sw))
        return beta[0]  # the affine fit at d = 0
