"""Extended-state observers (control/observers.py): the ESO (order 2) and the GPIO (order 3).

The plant is dw/dt = b u + d(t). With x = [w, d, dd/dt, ...] (order states) the chain of
integrators sampled with u held is x[k+1] = Phi x[k] + Gamma u[k], and the observer
``discrete_observer`` builds is z[k+1] = Phi z[k] + Gamma u[k] + L (w[k] - z1[k]), L placing
every eigenvalue of Phi - L C (C = [1, 0, ...]) at p = exp(-wo ts).

Every dynamic test drives the compiled ``observer_step`` with samples (u_k, w_k) of a trajectory
known in closed form. Indexing: ``observer_step(z, packed, u_k, w_k)`` maps the estimate at t_k
to the estimate at t_{k+1}; the runs below return Z[k] = estimate at t_k, Z[0] = 0.

The one fact behind the assertions: whenever the disturbance is a polynomial the observer models
(a constant for the ESO, a ramp for the GPIO) and w is the exact sample of the plant with u held,
the true state obeys x[k+1] = Phi x[k] + Gamma u[k] exactly, so the error e = x - z obeys
e[k+1] = (Phi - L C) e[k] exactly: no discretisation error is left, for any wo ts, only round-off.
A disturbance one degree higher (a ramp for the ESO) adds a constant forcing term to that
recursion, whose fixed point is the steady error.
"""

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from emasim.control.observers import (
    discrete_observer,
    observer_gains,
    observer_step,
    sampled_plant,
)

B_GAIN = 2.0  # b = kt / J of the test plant (any nonzero value; 2 checks it is not ignored)
EPS = np.finfo(float).eps


def continuous_observer(order: int, wo: float, b: float) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of the continuous observer written from the module docstring's equations, inputs
    [u, w]: z1' = -l1 z1 + z2 + b u + l1 w, z_i' = -l_i z1 + z_{i+1} + l_i w, z_n' = -l_n z1 +
    l_n w. A is also the matrix of the estimation error e = x - z (x = [w, d, d', ...]).
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


def integrator_chain(order: int, b: float, ts: float) -> tuple[np.ndarray, np.ndarray]:
    """Closed-form exact sampling of w' = b u + d, d' = d1, ... (u held): Phi = exp(N ts) with N
    the shift matrix, Phi[i, j] = ts^(j-i)/(j-i)! for j >= i; u enters w' only, so Gamma =
    [b ts, 0, ..., 0] (the d-chain is autonomous).
    """
    phi = np.zeros((order, order))
    for i in range(order):
        for j in range(i, order):
            phi[i, j] = ts ** (j - i) / math.factorial(j - i)
    gamma = np.zeros(order)
    gamma[0] = b * ts
    return phi, gamma


def unpack(packed: np.ndarray, order: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(Phi, Gamma, L) from the documented layout [Phi row-major, Gamma, L]."""
    assert packed.shape == (order * order + 2 * order,)
    n2 = order * order
    return packed[:n2].reshape(order, order), packed[n2 : n2 + order], packed[n2 + order :]


def error_matrix(order: int, wo: float, ts: float, b: float = B_GAIN) -> np.ndarray:
    """Phi - L C of the packed observer: e[k+1] = (Phi - L C) e[k] for e = x - z."""
    phi, _, gain = unpack(discrete_observer(order, wo, b, ts), order)
    c = np.zeros(order)
    c[0] = 1.0
    return phi - np.outer(gain, c)


def reference_gain(order: int, wo: float, ts: float) -> np.ndarray:
    """L placing every eigenvalue of Phi - L C at p, computed without Ackermann's formula.

    With y = z - 1, q = 1 - p and E = Phi - I (nilpotent),
    det(z I - Phi + L C) = det(z I - Phi) (1 + C (z I - Phi)^-1 L)
                         = y^n + sum_k y^(n-1-k) C E^k L,
    which equals (y + q)^n iff C E^k L = comb(n, k+1) q^(k+1) for k = 0 .. n-1: a triangular
    system (C E^k has its first nonzero entry ts^k in column k). q = -expm1(-wo ts) and no
    expanded polynomial, so it stays accurate to round-off for any wo ts.
    """
    e = integrator_chain(order, 0.0, ts)[0] - np.eye(order)
    rows = np.array([np.linalg.matrix_power(e, k)[0] for k in range(order)])
    q = -math.expm1(-wo * ts)
    rhs = np.array([math.comb(order, k + 1) * q ** (k + 1) for k in range(order)])
    return np.linalg.solve(rows, rhs)


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


def step_error(order, t, wo, size):
    """Continuous error d - z2 after a disturbance step of ``size`` at t = 0 (z(0) = 0).

    e(0) = [0, D, 0...]; E2(s) = D s (s + l1) / (s + wo)^n, so with x = wo t
    ESO: e2 = D e^{-x} (1 + x),  GPIO: e2 = D e^{-x} (1 + x - x^2)   (t >= 0; D before).
    """
    x = wo * np.asarray(t, dtype=float)
    poly = 1.0 + x if order == 2 else 1.0 + x - x * x
    return np.where(x >= 0.0, size * np.exp(-x) * poly, size)


def settling_time(t, err, size, band=0.02):
    """First time after which |err| stays within band * |size|."""
    outside = np.nonzero(np.abs(err) > band * abs(size))[0]
    return t[outside[-1] + 1] if outside.size else t[0]


def samples_for(wo_ts: float, time_constants: float = 40.0, minimum: int = 50) -> int:
    """Enough samples for ``time_constants`` observer time constants (x^2 e^-x ~ 1e-14 at 40)."""
    return max(minimum, math.ceil(time_constants / wo_ts))


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
    assert np.max(np.abs(roots + wo)) <= 10.0 * EPS ** (1.0 / order) * wo
    assert np.mean(roots).real == pytest.approx(-wo, rel=1e-12)
    if order == 2:
        np.testing.assert_allclose(observer_gains(2, wo), [2 * wo, wo**2], rtol=1e-15)
    if order == 3:
        np.testing.assert_allclose(observer_gains(3, wo), [3 * wo, 3 * wo**2, wo**3], rtol=1e-15)


@pytest.mark.parametrize("order", [1, 2, 3, 4])
@pytest.mark.parametrize("ts", [1e-4, 1e-3])
def test_phi_gamma_are_the_exact_sampling_of_the_integrator_chain(order, ts):
    """``sampled_plant`` and the packed Phi, Gamma equal the closed forms of ``integrator_chain``
    (relative 1e-14 on every nonzero entry, measured <= 1.6e-16; the structural zeros to 1e-15
    of the smallest entry): Phi[i, j] = ts^(j-i)/(j-i)!, Gamma = [b ts, 0, ...]. The packed
    values do not depend on wo, and the layout is [Phi row-major, Gamma, L].
    """
    phi_ref, gamma_ref = integrator_chain(order, B_GAIN, ts)
    tiny = 1e-15 * ts ** (order - 1) / math.factorial(order - 1)
    phi, gamma = sampled_plant(order, B_GAIN, ts)
    np.testing.assert_allclose(phi, phi_ref, rtol=1e-14, atol=tiny)
    np.testing.assert_allclose(gamma, gamma_ref, rtol=1e-14, atol=tiny * B_GAIN * ts)
    for wo_ts in (0.005, 1.0, 5.0):
        packed = discrete_observer(order, wo_ts / ts, B_GAIN, ts)
        packed_phi, packed_gamma, _ = unpack(packed, order)
        np.testing.assert_array_equal(packed_phi, phi)
        np.testing.assert_array_equal(packed_gamma, gamma)


@pytest.mark.parametrize("order", [1, 2, 3, 4])
@pytest.mark.parametrize("wo_ts", [0.005, 0.5, 5.0])
def test_error_poles_are_all_at_exp_minus_wo_ts(order, wo_ts):
    """Phi - L C has characteristic polynomial (z - p)^n, p = exp(-wo ts): coefficients to
    1e-12 absolute (they are at most comb(n, n/2); measured <= 1.4e-14). Its eigenvalues, a
    root of multiplicity n, are within 10 eps^(1/n) of p (absolute: discrete eigenvalues live
    on the scale 1; measured <= 1.6 eps^(1/n)), and so is the spectral radius.
    """
    ts = 1e-4
    p = math.exp(-wo_ts)
    m = error_matrix(order, wo_ts / ts, ts)
    np.testing.assert_allclose(np.poly(m), np.poly(np.full(order, p)), rtol=0, atol=1e-12)
    eig = np.linalg.eigvals(m)
    tol = 10.0 * EPS ** (1.0 / order)
    assert np.max(np.abs(eig - p)) <= tol
    assert np.max(np.abs(eig)) == pytest.approx(p, abs=tol)


@pytest.mark.parametrize("order", [1, 2, 3, 4])
@pytest.mark.parametrize("wo_ts", [0.01, 0.1, 1.0, 5.0])
def test_gain_matches_the_independent_pole_placement(order, wo_ts):
    """L equals ``reference_gain`` (the triangular pole-placement conditions, not Ackermann):
    relative 1e-11 for wo ts >= 0.1 (measured <= 6.3e-13), 1e-8 at wo ts = 0.01 (measured
    4.4e-13, 1.6e-10, 9.3e-10 for orders 2, 3, 4: the src loses accuracy as wo ts -> 0, see the
    test below). Order 2 also against its closed form L = [2 q, q^2 / ts], q = 1 - p.

    Continuous limit: L / ts -> observer_gains(order, wo) as wo ts -> 0. For the first and
    last gains the ratio is exactly q/(wo ts) and (q/(wo ts))^n, both in [1 - n wo ts/2, 1);
    asserted for every gain at wo ts = 0.01 (measured: all within that band).
    """
    ts = 1e-4
    wo = wo_ts / ts
    _, _, gain = unpack(discrete_observer(order, wo, B_GAIN, ts), order)
    reference = reference_gain(order, wo, ts)
    np.testing.assert_allclose(gain, reference, rtol=1e-11 if wo_ts >= 0.1 else 1e-8)
    q = -math.expm1(-wo_ts)
    if order == 2:
        np.testing.assert_allclose(reference, [2.0 * q, q * q / ts], rtol=1e-14)
    if wo_ts == 0.01:
        ratio = gain / (ts * observer_gains(order, wo))
        assert np.all(ratio < 1.0)
        assert np.all(ratio >= 1.0 - order * wo_ts / 2.0 - 1e-12)


@pytest.mark.parametrize(("order", "wo_ts"), [(3, 1e-4), (4, 1e-3)])
def test_gain_is_accurate_at_small_wo_ts(order, wo_ts):
    """L stays accurate at small wo ts. Expanding (z - p)^n into coefficients and summing them
    at Phi would cancel all but ~eps / (wo ts)^n of relative accuracy (GPIO 9.4e-5 at
    wo ts = 1e-4, order 4: 0.11); building P(Phi) as (Phi - I + q I)^n with
    q = -expm1(-wo ts) keeps it at round-off level."""
    ts = 1e-4
    wo = wo_ts / ts
    _, _, gain = unpack(discrete_observer(order, wo, B_GAIN, ts), order)
    np.testing.assert_allclose(gain, reference_gain(order, wo, ts), rtol=1e-9)


@pytest.mark.parametrize("order", [1, 2, 3, 4])
def test_observer_step_applies_the_packed_update_in_place(order):
    """One compiled step on random data equals Phi z + Gamma u + L (w - z1) computed with
    numpy from the unpacked arrays (relative 1e-13), written into the same array.
    """
    rng = np.random.default_rng(order)
    ts, wo = 1e-3, 300.0
    packed = discrete_observer(order, wo, B_GAIN, ts)
    phi, gamma, gain = unpack(packed, order)
    for _ in range(5):
        z = rng.normal(size=order)
        u, w = rng.normal(), rng.normal()
        expected = phi @ z + gamma * u + gain * (w - z[0])
        before = z
        observer_step(z, packed, u, w)
        assert z is before
        np.testing.assert_allclose(z, expected, rtol=1e-13, atol=1e-13 * np.max(np.abs(expected)))


@pytest.mark.parametrize("order", [2, 3])
@pytest.mark.parametrize("wo_ts", [0.005, 0.05, 0.5, 1.0, 2.0, 5.0])
def test_step_disturbance_is_estimated_exactly(order, wo_ts):
    """d = D from t = 0 (u = 0, w = D t sampled exactly), z(0) = 0, run for 40 observer time
    constants (8000 samples at wo ts = 0.005, 50 at >= 0.8): the model is exact, so z2 -> D,
    z1 -> w (and z3 -> 0 for the GPIO) with no discretisation bias for any wo ts, to round-off.
    Asserted |z2 - D| <= 1e-9 D (measured <= 1.7e-13 D; the former ZOH design was off by
    ~(wo ts)^2 / 4 for the GPIO: 6e-6 at 0.005, -0.35 D at 5), |z1 - w| <= 1e-12 |w| (measured
    <= 5e-15) and |z3| <= 1e-9 D wo (measured <= 2.5e-14 D wo).
    """
    ts, size = 1e-4, 1.5
    wo = wo_ts / ts
    n = samples_for(wo_ts)
    t = np.arange(n + 1) * ts
    w = size * t
    trace = run_observer(order, wo, ts, w[:-1])
    assert trace[-1, 1] == pytest.approx(size, rel=1e-9)
    assert trace[-1, 0] == pytest.approx(w[-1], rel=1e-12)
    if order == 3:
        assert abs(trace[-1, 2]) <= 1e-9 * size * wo


@pytest.mark.parametrize("wo_ts", [0.005, 0.5, 5.0])
def test_ramp_disturbance_gpio_has_no_steady_error(wo_ts):
    """d = a t, u = 0, w = a t^2/2 sampled exactly; 40 time constants. For the GPIO the ramp is
    in the model (x = [w, d, a], x[k+1] = Phi x[k] exactly), so z2 - d -> 0 and z3 -> a with no
    lag, for any wo ts. Asserted over the last 10 % of the run: |z2 - d| <= 1e-9 a t_end
    (measured <= 2.5e-13 a t_end; the ZOH design drifted as a (wo ts)^2 t / 4) and z3 = a to
    1e-9 relative (measured <= 2.8e-12).
    """
    ts, a = 1e-4, 3.0
    wo = wo_ts / ts
    n = samples_for(wo_ts)
    t = np.arange(n + 1) * ts
    trace = run_observer(3, wo, ts, a * t[:-1] ** 2 / 2.0)
    tail = slice(n - n // 10, None)
    assert np.max(np.abs(trace[tail, 1] - a * t[tail])) <= 1e-9 * a * t[-1]
    np.testing.assert_allclose(trace[tail, 2], a, rtol=1e-9)


def eso_ramp_fixed_point(wo, ts, a):
    """Steady error e* = x - z of the ESO under d = a t, from e[k+1] = M e[k] + f.

    f = x[k+1] - Phi x[k] for x = [a t^2/2, a t] is the ramp's effect beyond the model,
    [a ts^2/2, a ts] for every k (computed here from the trajectory at two instants). The fixed
    point solves (I - M) e* = f.
    """
    phi, _ = integrator_chain(2, B_GAIN, ts)
    forcing = []
    for t0 in (0.0, 0.37):
        x0 = np.array([a * t0**2 / 2.0, a * t0])
        x1 = np.array([a * (t0 + ts) ** 2 / 2.0, a * (t0 + ts)])
        forcing.append(x1 - phi @ x0)
    np.testing.assert_allclose(forcing[0], forcing[1], rtol=1e-9)
    return np.linalg.solve(np.eye(2) - error_matrix(2, wo, ts), forcing[0])


@pytest.mark.parametrize("wo_ts", [0.005, 0.5, 5.0])
def test_ramp_disturbance_eso_settles_at_the_discrete_fixed_point(wo_ts):
    """d = a t (ramp, one degree beyond the ESO's model): the error recursion gets a constant
    forcing f and z2 - d settles at -e2*, the fixed point of ``eso_ramp_fixed_point``.
    Asserted over the last 10 % of 40 time constants: z2 - d = -e2* to 1e-9 relative
    (measured <= 3.3e-12). Solving the 2 x 2 system by hand (L = [2q, q^2/ts]):
    e2* = 2 a ts / q - a ts / 2, checked to 1e-12 (measured 0.12015, 1.3749e-3 and 4.5407e-4
    for a = 3, wo ts = 0.005, 0.5, 5 at ts = 1e-4, i.e. 2a/wo (1 + wo ts/4 + ...) at small
    wo ts, 3.78 times 2a/wo at wo ts = 5).
    """
    ts, a = 1e-4, 3.0
    wo = wo_ts / ts
    fixed = eso_ramp_fixed_point(wo, ts, a)
    q = -math.expm1(-wo_ts)
    assert fixed[1] == pytest.approx(2.0 * a * ts / q - a * ts / 2.0, rel=1e-12)
    n = samples_for(wo_ts)
    t = np.arange(n + 1) * ts
    trace = run_observer(2, wo, ts, a * t[:-1] ** 2 / 2.0)
    tail = slice(n - n // 10, None)
    np.testing.assert_allclose(trace[tail, 1] - a * t[tail], -fixed[1], rtol=1e-9)


@pytest.mark.parametrize("wo_ts", [1e-3, 1e-2])
def test_eso_ramp_lag_tends_to_the_continuous_2a_over_wo(wo_ts):
    """As wo ts -> 0 the discrete fixed point e2* tends to the docstring's continuous lag
    l1 a / l2 = 2a/wo: e2* / (2a/wo) - 1 = wo ts / 4 + O((wo ts)^2) (from 1/q = 1/(wo ts) + 1/2
    + wo ts/12 + ...). Asserted: within 1 % of 2a/wo at wo ts = 1e-3, and the relative excess
    equal to wo ts / 4 within 1 % (measured 2.5008e-4 and 2.5083e-3).
    """
    ts, a = 1e-4, 3.0
    wo = wo_ts / ts
    fixed = eso_ramp_fixed_point(wo, ts, a)
    excess = fixed[1] / (2.0 * a / wo) - 1.0
    if wo_ts == 1e-3:
        assert fixed[1] == pytest.approx(2.0 * a / wo, rel=0.01)
    assert excess == pytest.approx(wo_ts / 4.0, rel=0.01)


@pytest.mark.parametrize("order", [2, 3])
@pytest.mark.parametrize("wo", [20.0, 40.0])
def test_step_error_is_the_discrete_error_system_response(order, wo):
    """d = D for t >= 0 (u = 0, w = D t sampled exactly), z(0) = 0, ts = 1e-4 (wo ts = 0.002,
    0.004), 1 s. The sampled error d - z2 is the second component of (Phi - L C)^k e0,
    e0 = [0, D, 0...], computed with numpy matrix powers on every 7th sample (and the first
    20): asserted to 1e-9 D (measured <= 3.7e-13 D).

    Against the continuous response e2(t_k) of ``step_error`` the difference is first order in
    wo ts: asserted <= 0.5 wo ts D; measured 0.184 wo ts D (ESO) and 0.347 (GPIO), the same at
    ts = 1e-3. Observed: with the error system exact, what is left of the continuous limit is
    the predictor form, z[k+1] built from w[k] (e[1] = e[0]: the first sample cannot see d).
    Expanding the discrete response p^k (c0 + c1 k + c2 k^2) in wo ts gives
      ESO:  e2(t_k - ts/2) + O((wo ts)^2)                      (a half-sample delay only)
      GPIO: e2(t_k - ts/2) - (wo ts / 4) D x^2 e^-x + O((wo ts)^2),  x = wo t_k
    (the delay plus a first-order change of the response shape: the poles map exactly, the
    zeros do not). Asserted to (wo ts)^2 D / 2; measured 0.125 (ESO) and 0.375 (GPIO)
    (wo ts)^2 D.
    """
    size, ts = 1.5, 1e-4
    n = round(1.0 / ts)
    t = np.arange(n + 1) * ts
    err = size - run_observer(order, wo, ts, size * t[:-1])[:, 1]

    m = error_matrix(order, wo, ts)
    e0 = np.zeros(order)
    e0[1] = size
    ks = np.union1d(np.arange(20), np.arange(0, n + 1, 7))
    predicted = np.array([(np.linalg.matrix_power(m, k) @ e0)[1] for k in ks])
    np.testing.assert_allclose(err[ks], predicted, rtol=0, atol=1e-9 * size)

    h = wo * ts
    assert np.max(np.abs(err - step_error(order, t, wo, size))) <= 0.5 * h * size
    x = wo * t
    first_order = step_error(order, t - ts / 2.0, wo, size)
    if order == 3:
        first_order -= h / 4.0 * size * x * x * np.exp(-x)
    assert np.max(np.abs(err - first_order)) <= 0.5 * h * h * size


def test_gpio_settling_time_scales_as_one_over_wo():
    """2 % settling of d - z2 after a step: the closed form gives t_s = x_s / wo with x_s the
    last root of e^{-x}(x^2 - x - 1) = 0.02 (x_s = 7.889). The discrete error crosses the band
    0.90 samples later (the first-order terms of the test above, divided by the slope at t_s),
    so the first sample after which it stays inside lies 0.9 to 1.9 samples after x_s / wo.
    Measured at wo = 20 and 40 (ts = 1e-4): 0.3946 s and 0.1974 s, 1.6 and 1.8 samples late;
    ratio 1.999. Asserted: x_s / wo < t_s <= x_s / wo + 2 ts, and the ratio within 1 % of 2.
    """
    x_s = brentq(lambda x: math.exp(-x) * (x * x - x - 1.0) - 0.02, 3.0, 20.0)
    size, ts = 1.0, 1e-4
    n = round(0.8 / ts)
    t = np.arange(n + 1) * ts
    times = []
    for wo in (20.0, 40.0):
        err = size - run_observer(3, wo, ts, size * t[:-1])[:, 1]
        times.append(settling_time(t, err, size))
        assert x_s / wo < times[-1] <= x_s / wo + 2 * ts
    assert times[0] / times[1] == pytest.approx(2.0, rel=0.01)


def forward_euler_spectral_radius(order, wo, ts):
    a, _ = continuous_observer(order, wo, B_GAIN)
    return float(np.max(np.abs(np.linalg.eigvals(np.eye(order) + ts * a))))


@pytest.mark.parametrize("order", [2, 3])
@pytest.mark.parametrize("wo_ts", [2.0, 5.0])
def test_sampled_design_converges_where_forward_euler_diverges(order, wo_ts):
    """wo ts = 2 and 5 (ts = 1e-3): forward Euler of the continuous observer, z+ = (I + ts A) z
    + ..., has every eigenvalue at 1 - wo ts (modulus 1 with a Jordan block at 2, 4 at 5:
    unstable), shown both by its spectral radius and by running it on the same input, which
    runs away (beyond 100 D). The sampled design has spectral radius exp(-wo ts) < 1 (to
    10 eps^(1/n), as above) and under a step disturbance D its estimates converge to the right
    values within 0.5 s (1000-2500 time constants): z2 = D to 1e-9 relative (measured
    <= 2.9e-14) and z1 = w to 1e-12 relative (measured exact).

    The transient is bounded in closed form: z[1] = L (w0 - 0) = 0 and z[2] = L D ts, so
    z2[2] = L2 ts D = q^2 D (ESO) or (3 q^2 - q^3/2) D (GPIO, from ``reference_gain``),
    q = 1 - exp(-wo ts); asserted to 1e-12. For the GPIO that is the peak of |z2| (measured
    1.92 D and 2.47 D at wo ts = 2, 5; asserted, and below the deadbeat limit q = 1: 2.5 D).
    The ESO's error is D p^k (1 + (1/p - 1) k) > 0 (fixed by e2[0] = e2[1] = D), so its z2
    rises to D without overshoot: asserted max |z2| <= D (1 + 1e-12).
    """
    wo, ts, size = wo_ts / 1e-3, 1e-3, 1.0
    assert forward_euler_spectral_radius(order, wo, ts) >= 1.0 - 1e-6
    radius = np.max(np.abs(np.linalg.eigvals(error_matrix(order, wo, ts))))
    assert radius == pytest.approx(math.exp(-wo_ts), abs=10.0 * EPS ** (1.0 / order))
    assert radius < 1.0

    n = 500
    t = np.arange(n + 1) * ts
    w = size * t
    trace = run_observer(order, wo, ts, w[:-1])
    assert np.all(np.isfinite(trace))
    q = -math.expm1(-wo_ts)
    peak = q * q if order == 2 else 3.0 * q * q - q**3 / 2.0
    assert trace[2, 1] == pytest.approx(peak * size, rel=1e-12)
    if order == 2:  # e2[k] = D p^k (1 + (1/p - 1) k) > 0: z2 rises to D without overshoot
        assert np.max(np.abs(trace[:, 1])) <= size * (1.0 + 1e-12)
    else:  # the GPIO overshoots at k = 2, at most to the deadbeat 2.5 D
        assert np.max(np.abs(trace[:, 1])) == pytest.approx(peak * size, rel=1e-12)
        assert peak <= 2.5
    assert trace[-1, 1] == pytest.approx(size, rel=1e-9)
    assert trace[-1, 0] == pytest.approx(w[-1], rel=1e-12)

    a, inputs = continuous_observer(order, wo, B_GAIN)
    euler, z = np.eye(order) + ts * a, np.zeros(order)
    with np.errstate(over="ignore", invalid="ignore"):
        for k in range(n):
            z = euler @ z + ts * inputs[:, 1] * w[k]
    # forward Euler runs away (to ~1e3 D at wo ts = 2, where the Jordan block grows linearly;
    # to overflow at wo ts = 5); NaN counts as diverged
    assert not np.all(np.abs(z) < 100.0 * size)


@pytest.mark.parametrize("order", [2, 3])
def test_known_input_is_not_taken_for_a_disturbance(order):
    """u = U sin(2 pi 5 t) held over each sample, w integrated exactly (w[k+1] = w[k] + b u[k]
    ts), 1 s at wo = 50, ts = 1e-4. With d = 0 the model is exact and e(0) = 0, so z = x from
    the first sample on: |z2| <= 1e-12 b U and |z1 - w| <= 1e-12 b U over the whole run
    (measured 0: Gamma u adds exactly what the cumulative sum adds). A wrong sign of b would
    give |z2| ~ 2 b U (measured 2.9 ESO, 5.2 GPIO after 0.5 s). With a step disturbance D added
    to the same input, z2 -> D: asserted to 1e-9 D over the last 0.1 s (45 time constants;
    measured 1.2e-13 D).
    """
    wo, ts, amp, omega, size = 50.0, 1e-4, 1.0, 2.0 * math.pi * 5.0, 1.5
    n = round(1.0 / ts)
    t = np.arange(n + 1) * ts
    u = amp * np.sin(omega * t[:-1])
    w = np.concatenate([[0.0], np.cumsum(B_GAIN * u * ts)])  # exact for u held over a sample
    trace = run_observer(order, wo, ts, w[:-1], u)
    assert np.max(np.abs(trace[:, 1])) <= 1e-12 * B_GAIN * amp
    assert np.max(np.abs(trace[:, 0] - w)) <= 1e-12 * B_GAIN * amp

    w_d = np.concatenate([[0.0], np.cumsum((B_GAIN * u + size) * ts)])
    trace = run_observer(order, wo, ts, w_d[:-1], u)
    np.testing.assert_allclose(trace[t >= 0.9, 1], size, rtol=1e-9)
