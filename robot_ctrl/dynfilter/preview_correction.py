"""PreviewCorrection: the CoM offset whose cart-table ZMP cancels a predicted ZMP error (Kajita et
al. 2003, preview control, in its batch form over the pattern generator's horizon).

Per horizontal axis the offset has the cart-table state ``Δx̂ = [Δc, Δċ, Δc̈]`` driven by jerks ``ΔU``
over N samples of length T (``wpg.lipm``). Given the ZMP error ``e_j`` (multibody minus reference) at
the samples, and the offset's current ZMP change ``Δz⁽ᵏ⁾``, one Newton step aims at
``Z* = Δz⁽ᵏ⁾ − e``::

    ΔU = argmin ‖W (Pzs Δx̂₀ + Pzu ΔU − Z*)‖² + r_u ‖ΔU‖² + r_c ‖Pps Δx̂₀ + Ppu ΔU‖²

``W`` weighs the samples (the filter weighs double support down: there the ZMP may move anywhere in
the two-foot polygon, and chasing its fast transfer makes the offset jerk at every touch-down).
``r_c`` keeps the offset small and lets it return to zero when the error does. The state is
carried from sample to sample (``advance``) so the offset is continuous in position, velocity and
acceleration. World frame, SI units.
"""

from __future__ import annotations

import numpy as np

from robot_ctrl.wpg.lipm import com_at, horizon_matrices, transition


class PreviewCorrection:
    def __init__(self, horizon: int, com_height: float, jerk_weight: float = 1e-6, offset_weight: float = 0.2):
        """Weights chosen on the 3 m arm-swing walk (docs/dynamic-filter.md): a jerk weight of 1e-4 smooths the
        offset so much that it no longer cancels the error; 1e-6 with double support weighed down
        does."""
        self.N = horizon
        self.h = com_height
        self.r_u, self.r_c = jerk_weight, offset_weight
        self.state = np.zeros((3, 2))  # Δx̂ per axis (columns x, y)
        self.jerks = np.zeros((horizon, 2))
        self._T = None

    def _matrices(self, T: float):
        if T != self._T:
            self._T = T
            self.m = horizon_matrices(T, self.N, self.h)
        return self.m

    def zmp_change(self, T: float) -> np.ndarray:
        """Cart-table ZMP change (N, 2) of the current offset plan at samples 1..N."""
        m = self._matrices(T)
        return m.Pzs @ self.state + m.Pzu @ self.jerks

    def offsets(self, T: float) -> np.ndarray:
        """CoM offset (N + 1, 2) at samples 0..N of the current plan."""
        m = self._matrices(T)
        return np.vstack([self.state[0], m.Pps @ self.state + m.Ppu @ self.jerks])

    def newton_step(self, error: np.ndarray, T: float, weights: np.ndarray | None = None) -> None:
        """Update the jerks so the offset's ZMP change cancels ``error`` (N, 2) on top of the current
        one, sample j weighted by ``weights[j]`` (default 1)."""
        m = self._matrices(T)
        w2 = np.ones(self.N) if weights is None else np.asarray(weights, dtype=float) ** 2
        target = self.zmp_change(T) - error
        A = m.Pzu.T * w2
        normal = A @ m.Pzu + self.r_u * np.eye(self.N) + self.r_c * m.Ppu.T @ m.Ppu
        rhs = A @ (target - m.Pzs @ self.state) - self.r_c * m.Ppu.T @ (m.Pps @ self.state)
        self.jerks = np.linalg.solve(normal, rhs)

    def return_to_zero(self, T: float) -> None:
        """Jerks that lead the offset smoothly back to zero from its current state (the unfiltered
        plan): the Newton step towards no ZMP change at all."""
        self.newton_step(self.zmp_change(T), T)

    def advance(self, T: float) -> None:
        """Move the state one sample ahead and shift the jerk plan (warm start of the next sample)."""
        for axis in range(2):
            self.state[:, axis] = com_at(self.state[:, axis], self.jerks[0, axis], T)
        self.jerks = np.vstack([self.jerks[1:], self.jerks[-1:]])

    def at(self, tau: float) -> tuple[np.ndarray, np.ndarray]:
        """Offset position and velocity (2,) each, ``tau`` seconds into the current sample."""
        A, B = transition(tau)
        s = A[:2] @ self.state + np.outer(B[:2], self.jerks[0])  # both axes at once (columns)
        return s[0], s[1]
