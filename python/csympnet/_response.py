"""The frequency response of a driven model (docs/identification.md, "The frequency response").

Two views of the same map Φ̂_h(z; u_start, u_end), the fitted one-step map with its input held
between samples as the model holds it:

- linear(...): the map linearised at its equilibrium z* (Φ̂_h(z*; 0, 0) = z*),

      δz_{k+1} = A δz_k + B0 u_k + B1 u_{k+1},   A = DΦ̂_h(z*),  B0, B1 = ∂Φ̂_h/∂u_start, ∂u_end,

  whose response to u_k = Re(U e^{iωkh}) is δq_k = Re(G(ω) U e^{iωkh}) with

      G(ω) = P_q (e^{iωh} I − A)⁻¹ (B0 + e^{iωh} B1)        (d × m, the data's units).

  A is the model's exact Jacobian; B0 and B1 are central differences in the inputs at z*,
  which the kick enters linearly (the error is the flow's curvature times the step, checked
  against the simulated response in the tests). The modes are A's eigenvalues λ = e^{(−ζω ± iω√(1−ζ²))h}.
- simulated(...): the nonlinear map driven by u = a sin(ωt) on input j from z*, run until the
  response repeats, and the fundamental of the last periods fitted by least squares: amplitude
  and phase per output, after 25/γ̂ (the free motion decayed to 4e-6 of its start). At small a
  it is linear(...); at larger a a hardening or softening force moves and bends the resonance.
"""
import math

import numpy as np


# The most steps a simulated response runs before it is measured (a record damped so lightly
# that it has not settled by then is reported with "settled" False).
MAX_SETTLE_STEPS = 2_000_000


def equilibrium(model, h, start=None, iterations=50):
    """z* with Φ̂_h(z*; 0, 0) = z*, by Newton's method on Φ̂_h(z) − z with the model's exact
    Jacobian, from `start` (default: the origin of the data's coordinates; a damped map run from
    there when Newton does not converge). Raises ValueError when no fixed point is found."""
    dim = 2 * model.d
    z0 = np.zeros(dim) if start is None else np.asarray(start, dtype=float).reshape(dim)
    attempts = [z0]
    gamma = model.gamma or 0.0
    if gamma > 0.0:  # the damped motion settles near an equilibrium within a few 1/γ
        steps = int(min(max(10.0 / (gamma * h), 100), 200000))
        attempts.append(lambda: model.rollout(z0, h, steps=steps)[-1])
    for att in attempts:
        z = att() if callable(att) else att.copy()
        if not np.all(np.isfinite(z)):
            continue
        for _ in range(iterations):
            f = model.predict(z, h) - z
            if not np.all(np.isfinite(f)):
                break
            scale = max(1.0, float(np.max(np.abs(z))))
            if float(np.max(np.abs(f))) <= 1e-13 * scale:
                return z
            j = model.jacobian(z, h) - np.eye(dim)
            try:
                z = z - np.linalg.solve(j, f)
            except np.linalg.LinAlgError:
                break
        f = model.predict(z, h) - z
        if np.all(np.isfinite(f)) and float(np.max(np.abs(f))) <= 1e-10 * max(1.0, float(np.max(np.abs(z)))):
            return z
    raise ValueError("frequency response: the map has no equilibrium near the origin of the "
                     "data's coordinates (Newton's method did not converge); give one with "
                     "equilibrium=")


def input_matrices(model, z, h, scale=1e-6):
    """B0, B1 (2d × m): the step's derivatives in the inputs at its start and end, central
    differences at z with steps of `scale` (the kick enters linearly)."""
    m, dim = model.n_inputs, 2 * model.d
    t = np.array([0.0, h])
    b0, b1 = np.empty((dim, m)), np.empty((dim, m))
    for j in range(m):
        for which, out in ((0, b0), (1, b1)):
            u = np.zeros((2, m))
            u[which, j] = scale
            plus = model.simulate(z, t, u)[-1]
            u[which, j] = -scale
            minus = model.simulate(z, t, u)[-1]
            out[:, j] = (plus - minus) / (2.0 * scale)
    return b0, b1


def linear(model, omega, h, z_eq=None):
    """The linearised response at the angular frequencies omega (n,): a dict with "omega",
    "response" (n, d, m) complex (output q_i per unit of input j), "equilibrium" (2d,),
    "modes" (angular frequency and damping ratio of each oscillating mode of A)."""
    omega = np.asarray(omega, dtype=float).reshape(-1)
    if omega.size == 0 or not np.all(np.isfinite(omega)) or np.any(omega <= 0):
        raise ValueError("omega: expected positive finite angular frequencies")
    nyquist = math.pi / h
    if np.any(omega >= nyquist):
        raise ValueError(f"omega: every frequency must be below the Nyquist frequency pi/h = "
                         f"{nyquist:.6g} of the step h = {h:.6g}")
    z = equilibrium(model, h) if z_eq is None else np.asarray(z_eq, dtype=float)
    a = model.jacobian(z, h)
    b0, b1 = input_matrices(model, z, h)
    d = model.d
    eye = np.eye(2 * d)
    out = np.empty((omega.size, d, model.n_inputs), dtype=complex)
    for k, w in enumerate(omega):
        e = np.exp(1j * w * h)
        out[k] = np.linalg.solve(e * eye - a, b0 + e * b1)[:d]
    return {"omega": omega, "response": out, "equilibrium": z, "modes": modes_of(a, h)}


def modes_of(a, h):
    """[(angular frequency, damping ratio)] of the oscillating eigenvalue pairs of A, slowest
    first"""
    out = []
    for lam in np.linalg.eigvals(a):
        if lam.imag <= 0.0:
            continue
        s = np.log(lam) / h  # −ζω + iω√(1−ζ²)
        wn = abs(s)
        out.append((float(wn), float(-s.real / wn) if wn > 0 else float("nan")))
    return sorted(out)


def simulated(model, omega, amplitude, h, input_index=0, z_eq=None, settle_periods=None,
              measure_periods=8):
    """The response to u_j = amplitude sin(ωt) by simulation from z*, per frequency: a dict
    with "omega", "amplitude", "response" (n, d) complex (the fundamental of q per unit of
    input, as linear(...) gives it) and "settled" (n,) bool: whether the last two measured
    stretches agree to 1e-3 (a response that has not settled, or does not repeat, is False)."""
    omega = np.asarray(omega, dtype=float).reshape(-1)
    if not (math.isfinite(amplitude) and amplitude > 0):
        raise ValueError("amplitude: expected a positive finite input amplitude")
    m = model.n_inputs
    if not 0 <= input_index < m:
        raise ValueError(f"input_index: expected 0 to {m - 1}")
    z = equilibrium(model, h) if z_eq is None else np.asarray(z_eq, dtype=float)
    gamma = max(model.gamma or 0.0, 1e-12)
    d = model.d
    resp = np.empty((omega.size, d), dtype=complex)
    settled = np.zeros(omega.size, dtype=bool)
    for k, w in enumerate(omega):
        period = 2 * math.pi / w
        # the free motion's amplitude decays as e^{−γt/2}: after 25/γ to 4e-6 of its start
        settle = (settle_periods * period if settle_periods is not None
                  else max(25.0 / gamma, 4 * period))
        per = max(int(round(period / h)), 1)
        n_settle = min(int(math.ceil(settle / h)), MAX_SETTLE_STEPS)
        n_measure = 2 * measure_periods * per
        t = np.arange(n_settle + n_measure + 1) * h
        u = np.zeros((t.size, m))
        u[:, input_index] = amplitude * np.sin(w * t)
        q = model.simulate(z, t, u)[:, :d] - z[:d]
        fits = []
        for part in (slice(n_settle, n_settle + n_measure // 2),
                     slice(n_settle + n_measure // 2, n_settle + n_measure)):
            tt = t[part]
            basis = np.column_stack([np.sin(w * tt), np.cos(w * tt), np.ones_like(tt)])
            coef, *_ = np.linalg.lstsq(basis, q[part], rcond=None)
            # u = a sin(ωt) = Re(-i a e^{iωt}); q = s sin + c cos = Re((c - i s) e^{iωt})
            fits.append((coef[1] - 1j * coef[0]) / (-1j * amplitude))
        resp[k] = fits[1]
        scale = max(float(np.max(np.abs(fits[1]))), 1e-300)
        settled[k] = bool(np.all(np.isfinite(fits[1]))
                          and float(np.max(np.abs(fits[1] - fits[0]))) <= 1e-3 * scale)
    return {"omega": omega, "amplitude": float(amplitude), "input_index": input_index,
            "response": resp, "settled": settled, "equilibrium": z}
