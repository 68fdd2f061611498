"""Extended-state observers (control/observers.py): the ESO (order 2) and the GPIO (order 3).

The plant is dw/dt = b u + d(t). Every test drives the compiled ``observer_step`` with samples
(u_k, w_k) of a trajectory known in closed form, the observer discretised by
``discrete_observer`` (ZOH). Indexing: ``observer_step(z, packed, u_k, w_k)`` maps the estimate
at t_k to the estimate at t_{k+1}; the runs below return Z[k] = estimate at t_k, Z[0] = 0.

The ZOH treats the measured w as held over each sample, whereas the true w moves within it: to
first order the observer sees w delayed by half a sample. That single fact predicts every
discretisation error asserted here (the -a ts/2 bias on a ramp, the ts/2 shift of the step
response); the tolerances follow from it.
"""

import math

import numpy as np
import pytest
from scipy.linalg import expm
from scipy.optimize import brentq

from emasim.control.observers import discrete_observer, observer_gains, observer_step

B_GAIN = 2.0  # b = kt / J of the test plant (any nonzero value; 2 checks it is not ignored)


def continuous_observer(order: int, wo: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of the observer written from the module docstring's equations, inputs [u, w]:
    z1' = -l1 z1 + z2 + b u + l1 w, z_i' = -l_i z1 + z_{i+1} + l_i w, z_n' = -l_n z1 + l_n w.
    A is also the matrix of the estimation error e = x - z (x = [w, d, d', ...]).
    """
    gains = observer_gains(order, wo)
    a = np.zeros((order, order))
    for i in range(order):
        a[i, 0] = -gains[i]
        if i + 1 < order:
            a[i, i + 1] = 1.0
    inputs = np.zeros((order, 2))
    inputs[0, 0] = b
    inputs[:, 1] = gains
    return a, inputs


def run_observer(order, wo, ts, w, u=None, b=B_GAIN) -> np.ndarray:
    """Drive the compiled observer_step with samples w[k] (and u[k], default 0) from z = 0.

    Returns Z of shape (len(w) + 1, order), Z[k] the estimate at t_k.
    """
    packed = discrete_observer(order, wo, b, ts)
    u = np.zeros(len(w)) if u is None else u
    z = np.zeros(order)
    trace = np.empty((len(w) + 1, order))
    trace[0] = z
    for k in range(len(w)):
        observer_step(z, packed, float(u[k]), float(w[k]))
        trace[k + 1] = z
    return trace


def gpio_step_error(t, wo, size):
    """Continuous GPIO error d - z2 after a disturbance step of ``size`` at t = 0 (z(0) = 0).

    With e(0) = [0, D, 0], E2(s) = D s (s + 3 wo) / (s + wo)^3, so
    e2(t) = D exp(-wo t) (1 + wo t - (wo t)^2) for t >= 0 (and D before).
    """
    x = wo * np.asarray(t, dtype=float)
    return np.where(x >= 0.0, size * np.exp(-x) * (1.0 + x - x * x), size)


def settling_time(t, err, size, band=0.02):
    """First time after which |err| stays within band * |size|."""
    outside = np.nonzero(np.abs(err) > band * abs(size))[0]
    return t[outside[-1] + 1] if outside.size else t[0]


@pytest.mark.parametrize("order", [1, 2, 3, 4])
@pytest.mark.parametrize("wo", [10.0, 2.0 * math.pi * 200.0])
def test_gains_place_every_pole_at_minus_wo(order, wo):
    """The error matrix built from the docstring equations has characteristic polynomial
    (s + wo)^order (coefficients to 1e-12 relative) and so all roots at -wo. A root of
    multiplicity n moves by ~eps^(1/n) relative under rounding of the coefficients (measured
    1.5e-8, 1.1e-5, 2.2e-4 for n = 2, 3, 4: 1.0-1.8 eps^(1/n)), hence the tolerance
    10 eps^(1/n) on each root; their mean (the trace) is -wo to 1e-12. Also pins the
    documented gains of orders 2 and 3.
    """
    a, _ = continuous_observer(order, wo, B_GAIN)
    expected = [math.comb(order, i) * wo**i for i in range(order + 1)]
    np.testing.assert_allclose(np.poly(a), expected, rtol=1e-12)
    roots = np.roots(np.poly(a))
    assert np.max(np.abs(roots + wo)) <= 10.0 * np.finfo(float).eps ** (1.0 / order) * wo
    assert np.mean(roots).real == pytest.approx(-wo, rel=1e-12)
    if order == 2:
        np.testing.assert_allclose(observer_gains(2, wo), [2 * wo, wo**2], rtol=1e-15)
    if order == 3:
        np.testing.assert_allclose(observer_gains(3, wo), [3 * wo, 3 * wo**2, wo**3], rtol=1e-15)


@pytest.mark.parametrize("order", [2, 3])
def test_discrete_observer_is_the_zoh_sampling_of_the_documented_one(order):
    """Packed [Ad, Bd] equals expm of the augmented matrix [[A, B], [0, 0]] ts of the observer
    written independently from the docstring (to 1e-12), and Ad's eigenvalues are the images
    exp(-wo ts) of the continuous poles (1e-5 relative: a multiple eigenvalue, as above).
    """
    wo, ts = 300.0, 1e-3
    a, inputs = continuous_observer(order, wo, B_GAIN)
    aug = np.zeros((order + 2, order + 2))
    aug[:order, :order], aug[:order, order:] = a, inputs
    expected = expm(aug * ts)[:order]
    packed = discrete_observer(order, wo, B_GAIN, ts)
    ad = packed[: order * order].reshape(order, order)
    bd = packed[order * order :].reshape(order, 2)
    np.testing.assert_allclose(ad, expected[:, :order], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(bd, expected[:, order:], rtol=1e-12, atol=1e-12 * wo**order)
    eig = np.linalg.eigvals(ad)
    np.testing.assert_allclose(np.abs(eig), math.exp(-wo * ts), rtol=1e-5)


def test_ramp_disturbance_gpio_tracks_and_eso_lags_by_2a_over_wo():
    """d = a t, u = 0, w = a t^2/2 sampled exactly; wo = 50 rad/s, ts = 1e-4 s, 1 s (50
    observer time constants: the transient, ~(wo t)^2 exp(-wo t), is gone).

    GPIO: z2 tracks d with no lag; what is left is the ZOH half-sample delay, -a ts/2.
    Asserted |z2 - d + a ts/2| <= 0.1 a ts; measured z2 - d = -0.5625 a ts (the 0.0625 is the
    slow drift noted in the xfail test below, a (wo ts)^2 t / 4 at t = 1 s). Also z3 -> a.
    ESO: z2 - d settles at -2a/wo (= -0.12 here), the docstring's closed form; asserted to
    a ts (0.25 % of the lag; measured -0.52 a ts beyond -2a/wo, the same half-sample delay).
    """
    a, wo, ts = 3.0, 50.0, 1e-4
    n = round(1.0 / ts)
    t = np.arange(n + 1) * ts
    w = a * t[:-1] ** 2 / 2.0
    tail = t >= 0.9
    gpio = run_observer(3, wo, ts, w)
    err_gpio = gpio[tail, 1] - a * t[tail]
    assert np.max(np.abs(err_gpio + a * ts / 2.0)) <= 0.1 * a * ts
    np.testing.assert_allclose(gpio[tail, 2], a, rtol=1e-3)
    eso = run_observer(2, wo, ts, w)
    err_eso = eso[tail, 1] - a * t[tail]
    assert np.max(np.abs(err_eso + 2.0 * a / wo)) <= a * ts
    assert np.max(np.abs(err_gpio)) < 2e-3 * (2.0 * a / wo)  # GPIO's error: < 0.2 % of ESO's


@pytest.mark.parametrize("order", [2, 3])
def test_known_input_is_not_taken_for_a_disturbance(order):
    """d = 0, u = U sin(2 pi 5 t) held over each sample, w integrated exactly: the b u path
    must explain all of w' so z2 stays ~0 (after 0.5 s of a 1 s run). A wrong sign of b would
    give |z2| ~ 2 b U (measured 5.2). The residual is the half-sample delay seen through the
    moving input, ~ b U W ts / 2 = 3.1e-3; asserted below twice that (measured 4.1e-3 GPIO,
    2.3e-3 ESO).
    """
    wo, ts, amp, omega = 50.0, 1e-4, 1.0, 2.0 * math.pi * 5.0
    n = round(1.0 / ts)
    t = np.arange(n + 1) * ts
    u = amp * np.sin(omega * t[:-1])
    w = np.concatenate([[0.0], np.cumsum(B_GAIN * u * ts)])  # exact for u held over a sample
    trace = run_observer(order, wo, ts, w[:-1], u)
    assert np.max(np.abs(trace[t >= 0.5, 1])) <= 2.0 * B_GAIN * amp * omega * ts / 2.0
    # z1 follows w to within one sample's travel b U ts (measured 1.2e-4, about half of it)
    np.testing.assert_allclose(trace[t >= 0.5, 0], w[t >= 0.5], atol=B_GAIN * amp * ts)


@pytest.mark.parametrize("wo", [20.0, 40.0])
def test_gpio_step_error_follows_the_triple_pole_response(wo):
    """d = D for t >= 0 (u = 0, w = D t sampled exactly), z(0) = 0: the sampled error d - z2
    against the continuous error of the triple pole at -wo, e2 = D e^{-x}(1 + x - x^2), x = wo t.

    ts = 1e-4 (wo ts = 0.002-0.004). Tolerances from the half-sample delay of the ZOH: against
    e2(t_k) the difference is about max|e2'| ts/2 = 0.40 wo ts D (max|e2'| = 0.80 D wo); asserted
    <= 0.5 wo ts D (measured 0.40 wo ts D). Against e2(t_k - ts/2) what is left is second order,
    asserted <= (wo ts)^2 D (measured 0.37 (wo ts)^2 D, i.e. 1.5e-6 D at wo = 20).
    """
    size, ts = 1.5, 1e-4
    n = round(1.0 / ts)
    t = np.arange(n + 1) * ts
    err = size - run_observer(3, wo, ts, size * t[:-1])[:, 1]
    assert np.max(np.abs(err - gpio_step_error(t, wo, size))) <= 0.5 * wo * ts * size
    delayed = gpio_step_error(t[1:] - ts / 2.0, wo, size)
    assert np.max(np.abs(err[1:] - delayed)) <= (wo * ts) ** 2 * size


def test_gpio_settling_time_scales_as_one_over_wo():
    """2 % settling of d - z2 after a step: the closed form gives t_s = x_s / wo with x_s the
    last root of e^{-x}(x^2 - x - 1) = 0.02 (x_s = 7.889). Measured at wo = 20 and 40 (ts = 1e-4):
    0.3945 s and 0.1973 s, i.e. x_s/wo to within a sample; the ratio is 2 to within 0.1 %.
    Asserted: each within 2 samples of x_s / wo, and the ratio within 1 % of 2.
    """
    x_s = brentq(lambda x: math.exp(-x) * (x * x - x - 1.0) - 0.02, 3.0, 20.0)
    size, ts = 1.0, 1e-4
    n = round(0.8 / ts)
    t = np.arange(n + 1) * ts
    times = []
    for wo in (20.0, 40.0):
        err = size - run_observer(3, wo, ts, size * t[:-1])[:, 1]
        times.append(settling_time(t, err, size))
        assert times[-1] == pytest.approx(x_s / wo, abs=2 * ts)
    assert times[0] / times[1] == pytest.approx(2.0, rel=0.01)


def forward_euler_spectral_radius(order, wo, ts):
    a, _ = continuous_observer(order, wo, B_GAIN)
    return float(np.max(np.abs(np.linalg.eigvals(np.eye(order) + ts * a))))


@pytest.mark.parametrize("order", [2, 3])
@pytest.mark.parametrize("wo_ts", [2.0, 5.0])
def test_zoh_observer_is_stable_where_forward_euler_is_not(order, wo_ts):
    """wo ts = 2 and 5 (ts = 1e-3): forward Euler z+ = (I + ts A) z + ... has every eigenvalue
    at 1 - wo ts (modulus 1 with a Jordan block at 2, 4 at 5: unstable), shown both by its
    spectral radius and by running it on the same input, which runs away (beyond 100 D). The
    ZOH observer has spectral radius exp(-wo ts) < 1: under a step disturbance D its estimates
    stay bounded (|z2| <= 3 D; measured <= 0.72 D) and converge (successive samples of z2 and
    of z1 - w agree to 1e-9 by the end of 0.5 s, i.e. 1000-2500 time constants; measured
    ~1e-14).

    Whether they converge to the right values is a separate question, see the xfail below
    (measured limits of z2: 0.72 D / 0.17 D for the ESO, 0.27 D / -0.35 D for the GPIO).
    """
    wo, ts, size = wo_ts / 1e-3, 1e-3, 1.0
    assert forward_euler_spectral_radius(order, wo, ts) >= 1.0 - 1e-6
    packed = discrete_observer(order, wo, B_GAIN, ts)
    ad = packed[: order * order].reshape(order, order)
    assert np.max(np.abs(np.linalg.eigvals(ad))) == pytest.approx(math.exp(-wo_ts), rel=1e-3)

    n = 500
    t = np.arange(n + 1) * ts
    w = size * t
    trace = run_observer(order, wo, ts, w[:-1])
    assert np.all(np.isfinite(trace))
    assert np.max(np.abs(trace[:, 1])) <= 3.0 * size
    assert abs(trace[-1, 1] - trace[-2, 1]) < 1e-9
    assert abs((trace[-1, 0] - w[-1]) - (trace[-2, 0] - w[-2])) < 1e-9

    a, inputs = continuous_observer(order, wo, B_GAIN)
    euler, z = np.eye(order) + ts * a, np.zeros(order)
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(n):
            z = euler @ z + ts * inputs[:, 1] * w[k]
    # the discretisation the ZOH replaces runs away (to ~1e3 D at wo ts = 2, where the Jordan
    # block grows linearly; to overflow at wo ts = 5); NaN counts as diverged
    assert not np.all(np.abs(z) < 100.0 * size)


@pytest.mark.xfail(
    strict=True,
    reason="ZOH on the measured w biases the disturbance estimate by O((wo ts)^2): "
    "GPIO z2 -> 0.27 D at wo ts = 2 and -0.35 D at 5; ESO 0.72 D and 0.17 D",
)
@pytest.mark.parametrize("order", [2, 3])
@pytest.mark.parametrize("wo_ts", [2.0, 5.0])
def test_large_wo_ts_estimate_converges_to_the_disturbance(order, wo_ts):
    """Known defect, kept as a strict xfail: "stable for any wo Ts" holds, but the limit is
    wrong when wo ts is not small. The ZOH treats w as a staircase, so for w = D t (a step
    d = D) z2 settles at ~D (1 - (wo ts)^2/4) for the GPIO, ~D (1 - (wo ts)^2/12) for the ESO
    at small wo ts (measured 1 - 6.25e-6 and 1 - 2.1e-6 at wo ts = 0.005; GPIO 0.9975 at 0.1,
    0.94 at 0.5, 0.77 at 1) and far off at large wo ts. Under a ramp d the same defect makes
    the GPIO's error grow as a (wo ts)^2 t / 4 instead of staying bounded. An observer designed
    on the exactly sampled plant model (Phi = expm(A0 ts) of the integrator chain, poles of
    Phi - L C at exp(-wo ts)) has z2 -> D exactly for any wo ts.
    Expected: z2 within 5 % of D after 0.5 s (>= 1000 time constants).
    """
    wo, ts, size = wo_ts / 1e-3, 1e-3, 1.0
    t = np.arange(501) * ts
    trace = run_observer(order, wo, ts, size * t[:-1])
    assert trace[-1, 1] == pytest.approx(size, rel=0.05)
