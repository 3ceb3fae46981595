"""The solar wind as it blows: a random factor on the E-sail's thrust.

The thrust is the nominal a_c (times the throttle) times a factor f(t), a stationary
Gauss-Markov (Ornstein-Uhlenbeck) process of mean 1, standard deviation ``sigma`` and
correlation time ``corr_days``:

    Cov[f(t), f(u)] = sigma^2 exp(-|t - u| / corr_days).

``sigma`` is the spread after whatever the sail does about it (such as lowering its
tether voltage in strong wind).  :data:`SIGMA` and :data:`CORR_DAYS` are round values
of the order Toivanen and Janhunen (2009) found, to be replaced by the analyst's own.

Each piece of a flight (a closed-form arc of constant a_c) gets the mean of f over its
span.  Those means are jointly Gaussian with the exact covariance, so a flight's total
impulse has the continuous process's variance whatever the pieces' lengths.  A piece
mean below 0 is flown as 0: the sail cannot pull toward the Sun.
"""

from dataclasses import dataclass

import numpy as np

from esail_opt.errors import check_range

#: Default standard deviation of the thrust factor (a fraction of the nominal).
SIGMA = 0.3
#: Default correlation time of the thrust factor, days.
CORR_DAYS = 1.0


@dataclass(frozen=True)
class SolarWind:
    """The thrust factor's law: mean 1, standard deviation ``sigma`` (a fraction, >= 0)
    and correlation time ``corr_days`` (days, > 0)."""

    sigma: float = SIGMA
    corr_days: float = CORR_DAYS

    def __post_init__(self):
        check_range("sigma", self.sigma, 0.0, 2.0)
        check_range("corr_days", self.corr_days, 0.0, float("inf"), low_open=True,
                    high_open=True, unit="d")

    def covariance(self, durations_days):
        """Covariance matrix of the factor's means over consecutive pieces of the given
        durations (days, >= 0; a zero-length piece has the factor's value at its
        instant), shape (K, K)."""
        span = np.asarray(durations_days, float)
        tau = self.corr_days
        ends = np.cumsum(span)
        starts = ends - span
        x = span / tau
        # The mean of exp(-|t - u| / tau) over one piece with itself, and the factor
        # (1 - exp(-x)) / x by which a piece's mean decays toward a later instant.
        small = x < 1e-8
        safe = np.where(small, 1.0, x)
        own = np.where(small, 1.0 - x / 3, 2 * (safe - 1 + np.exp(-safe)) / safe ** 2)
        reach = np.where(small, 1.0 - x / 2, -np.expm1(-safe) / safe)
        gap = np.maximum(starts[None, :] - ends[:, None], 0.0)  # piece j after piece i
        cov = reach[:, None] * reach[None, :] * np.exp(-gap / tau)
        cov = np.triu(cov, 1)
        cov = cov + cov.T + np.diag(own)
        return self.sigma ** 2 * cov

    def factors(self, durations_days, runs, seed):
        """``runs`` draws of the factor's piece means, shape (runs, K), floored at 0; all
        exactly 1 when ``sigma`` is 0.  The same seed gives the same draws."""
        k = len(durations_days)
        if self.sigma == 0:
            return np.ones((runs, k))
        cov = self.covariance(durations_days)
        # Eigen-factor rather than Cholesky: the means of long, strongly correlated
        # pieces make the matrix nearly singular.
        values, vectors = np.linalg.eigh(cov)
        root = vectors * np.sqrt(np.clip(values, 0.0, None))
        normal = np.random.default_rng(seed).standard_normal((runs, k))
        return np.maximum(1.0 + normal @ root.T, 0.0)
