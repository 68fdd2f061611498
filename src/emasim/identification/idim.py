"""Inverse-model least squares (IDIM-LS), the standard method of robot identification.

Where the force is linear in the parameters, tau = phi(q, qdot, qddot) theta (Gautier 1997;
Janot, Gautier, Brunot, *Data Set and Reference Models of EMPS*, 2019, section 3):

1. the bandpass: the measured position is filtered forward and backward by a Butterworth
   low-pass (order 4, cut-off ``cutoff_hz``: the EMPS reference's 5 x its 20 Hz position-loop
   bandwidth, the rule w_fq >= 5 w_dyn) and differentiated by central differences;
2. the decimation: every column of the observation matrix and the force are low-pass filtered
   in parallel and kept one sample in ``decimation`` (scipy.signal.decimate, zero phase: an
   order-8 Chebyshev I filter at 0.8 x the new Nyquist frequency, 80 Hz for 5 at 1 kHz,
   above the rule w_Fp >= 2 w_dyn);
3. the estimate theta = (Phi^T Phi)^-1 Phi^T y, the residual's variance
   s^2 = |y - Phi theta|^2 / (N - p), the standard deviations sqrt(diag(s^2 (Phi^T Phi)^-1))
   (emasim.identification.fit.spread: infinite for a column the others make up) and the
   relative error |y - Phi theta| / |y|.
"""

from dataclasses import dataclass

import numpy as np

from .fit import spread

BUTTERWORTH_ORDER = 4
CUTOFF_HZ = 100.0  # EMPS reference: 5 x 20 Hz
DECIMATION = 5


@dataclass(frozen=True)
class Derivatives:
    """The band-passed position (m), velocity (m/s) and acceleration (m/s^2)."""

    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray


def bandpass(position: np.ndarray, ts: float, cutoff_hz: float = CUTOFF_HZ) -> Derivatives:
    """Step 1 of the module docstring."""
    from scipy import signal

    b, a = signal.butter(BUTTERWORTH_ORDER, cutoff_hz * 2.0 * ts)
    q = signal.filtfilt(b, a, position)
    v = np.gradient(q, ts)
    return Derivatives(q, v, np.gradient(v, ts))


@dataclass(frozen=True)
class Estimate:
    """An IDIM-LS estimate: each parameter's value and standard deviation by name, the
    correlation matrix (in ``names`` order), the condition number of the observation matrix,
    the relative error and the samples kept."""

    names: tuple[str, ...]
    values: dict[str, float]
    std: dict[str, float]
    correlation: np.ndarray
    condition: float
    relative_error: float
    samples: int


def least_squares(
    regressors: dict[str, np.ndarray], force: np.ndarray, decimation: int = DECIMATION
) -> Estimate:
    """Steps 2 and 3 of the module docstring for the observation matrix's columns by name."""
    from scipy import signal

    names = tuple(regressors)
    phi = np.column_stack([regressors[n] for n in names])
    y = force
    if decimation > 1:
        phi = signal.decimate(phi, decimation, axis=0, zero_phase=True)
        y = signal.decimate(y, decimation, zero_phase=True)
    theta, *_ = np.linalg.lstsq(phi, y, rcond=None)
    residual = y - phi @ theta
    std, correlation = spread(phi, residual)
    return Estimate(
        names,
        dict(zip(names, (float(v) for v in theta), strict=True)),
        dict(zip(names, (float(s) for s in std), strict=True)),
        correlation,
        float(np.linalg.cond(phi)),
        float(np.linalg.norm(residual) / np.linalg.norm(y)),
        int(phi.shape[0]),
    )


def decimated_error(force: np.ndarray, model: np.ndarray, decimation: int = DECIMATION) -> float:
    """|y - y_model| / |y| of a force and its model, both decimated as :func:`least_squares`
    decimates (a cross-test on data the estimate did not see)."""
    from scipy import signal

    y = signal.decimate(force, decimation, zero_phase=True)
    residual = y - signal.decimate(model, decimation, zero_phase=True)
    return float(np.linalg.norm(residual) / np.linalg.norm(y))
