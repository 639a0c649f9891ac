"""Identification benchmark: recover the damping rate gamma of damped Hamiltonian systems from
snapshot data with `csympnet fit`, side by side with two peers, over >= 100 generated cases.

The package's modules, one job each: systems (the systems), simulation (RK4), violations
(data that break an assumption), generate (plans and data), peers/ (csympnet, sindy, oracle,
and the peers of the observed plan), runner (one case), tables (statistics and outputs), cli
(the options); observed (the observed-records plan: linear records in pixels, oversampled,
long, encoder counts, decays into the noise) with its own tables in observed_tables; forced
(the forced plan's driven systems, inputs, first-order-hold RK4 and records), forced_plan (one
forced case: linear ARX, polynomial NARX, the shooting oracle and csympnet, in peers/arx.py,
peers/narx.py, peers/forced_oracle.py, peers/csympnet.py) and forced_tables; friction (the
friction plan's exact decays with dry friction or drag, and an encoder-read pendulum with dry
friction), friction_chain (its two-mass records with dry friction on each mass), friction_plan (one case: csympnet, the oracle of peers/friction_oracle.py and the
envelope fit of peers/friction_textbook.py) and friction_tables.

Command (from the repository root; needs only /usr/bin/python3 with NumPy):

    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/idbench   # 120 cases
    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/b --fit-args="--epochs 2000"
    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/idq --quick --only-peers
    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/idv --violations  # 60
    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/idl --library \
        --systems all      # + csympnet_library; every system, the double pendulum included
    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/idf --forced-plan \
        --cases 9 --jobs 1 # driven systems: ARX, NARX, the oracle and csympnet side by side
    /usr/bin/python3 experiments/identification_benchmark.py --out /tmp/idfr --friction-plan \
        --cases 20         # dry friction and drag: csympnet, the oracle and the envelope fit

Options: --cases N (default 120, 8 with --quick; with --violations 60, 10 with --quick),
--quick (a few cases of small size), --violations (only violation cases, below), --seed S
(default 1; everything is deterministic given the seed), --only-peers (skip csympnet, and
csympnet_library), --systems a,b,... (a subset of the systems below, in the order given; "all":
every system; default: every system but double-pendulum, see below), --csympnet PATH (default
build/bin/csympnet under the repository root), --fit-args="..." (extra options for every
`csympnet fit`, split like a shell would; write it with "=" so that a value starting with "--"
is not taken for an option of this script), --timeout SECONDS (per fit, default 600),
--jobs N (cases in parallel, default 1), --force (reuse a non-empty --out), --momenta
given|gradient|savgol (the p columns as generated, default, or computed from the noisy q by
numpy.gradient or a Savitzky-Golay derivative, as a user without a momentum sensor would),
--observed (every case also fitted from its positions alone and with centred-difference
momenta, side by side: methods csympnet_positions and csympnet_differenced), --library
(every case also fitted with the Hamiltonian-library core forced: method csympnet_library; off
by default), --skip-peers (csympnet alone: no SINDy-style peer, no oracle; csympnet_library
still runs with --library), --observed-plan (the observed-records plan instead: --cases in all,
default 10, 5 with --quick; strata taken in turn) with --observed-strata a,b,... (a subset of
its strata; see idbench/observed.py for the strata, the peers and the CPU seconds),
--forced-plan (the forced-records plan instead: --cases in all, default 6, 3 with --quick; the
systems duffing, pendulum, duffing-chain taken in turn, each case a training multisine and two
test records, a multisine and a rising-amplitude filtered noise, positions only, with the input
columns u1..um; --forced-systems a,b,... a subset; see idbench/forced.py for the systems and
inputs and idbench/forced_plan.py for the methods and the free-run score). With --forced-plan,
csympnet is `csympnet fit` on the training file then `csympnet evaluate --warmup 100` on each
test file; a binary that refuses the input columns is recorded "unsupported" and the peers'
tables are written all the same. --friction-plan (the friction plan instead: --cases in all,
default 20, 5 with --quick; the strata viscous, coulomb, drag, coulomb-positions,
encoder-pendulum, coulomb-2dof and coulomb-2dof-positions taken in turn, --friction-strata a,b,... a subset; see idbench/friction.py for
the records and idbench/friction_plan.py for the methods and the scores).

Systems (dq/dt = M^-1 p, dp/dt = -grad V(q) - gamma p, unit masses, unless stated):

    pendulum            d = 1   V = -k cos q                          (libration)
    duffing             d = 1   V = -a q^2/2 + b q^4/4                (below or above the barrier)
    morse               d = 1   V = D (1 - exp(-a q))^2               (bound: E < D)
    linear              d = 1   V = k q^2/2, k = 25 (omega = 5)
    toda                d = 3..8  fixed ends, V = A sum exp(-b (q_{i+1} - q_i))
    fpu-alpha           d = 4, 8, 16  fixed ends, bond energy k x^2/2 + alpha x^3/3 (small)
    fpu-beta            d = 4, 8, 16  fixed ends, bond energy k x^2/2 + beta x^4/4
    henon-heiles        d = 2   V = w (q1^2 + q2^2)/2 + lam (q1^2 q2 - q2^3/3)   (E < 1/6)
    coupled-pendulums   d = 2   masses (1, 2.5), canonical momenta p_i = m_i dq_i/dt,
                                V = -g sum m_i cos q_i + kc (q1 - q2)^2/2
    softened-central    d = 2   V = -k / sqrt(|q|^2 + eps^2)          (bound orbits, E < 0)
    double-pendulum     d = 2   planar, unit lengths and masses, angles q1, q2 (from the
                                downward vertical; q2 absolute) and their canonical momenta:
                                H = (p1^2 + 2 p2^2 - 2 p1 p2 cos(q1 - q2))
                                    / (2 (1 + sin^2(q1 - q2))) - 2 g cos q1 - g cos q2,
                                theta = [g], g = 1; omega_max = sqrt(g (2 + sqrt 2)).
                                Starts: q_i, p_i uniform in [-0.8, 0.8], kept when the energy
                                above the minimum -3 g is in [0.05, 0.6] (so |q1| <= 0.80,
                                |q2| <= 1.16 rad at all times: bounded, mildly nonlinear)

The double pendulum's H is NOT separable (its kinetic energy depends on q1 - q2): it is outside
the class of csympnet's Hamiltonian-library core (H = p^T W p / 2 + V(q) with a constant W) and
is there to see what that core, and the default core choice, do on such data. Its dynamics are
dq/dt = dH/dp, dp/dt = -dH/dq - gamma p: the system supplies this field (make_system's
"field") and the data RK4 and the oracle integrate it instead of M^-1 p and grad V. It is not
in the default plan (the plan cycles through its system list, so adding a system there would
move every case of every seed; with it left out the default plans and data are those of
before): name it in --systems, or give --systems all. It has no violation cases.

The dissipation -gamma p acts on the canonical momenta, so every flow is conformally
symplectic. Trajectories are integrated with a fixed-substep classical RK4 (omega_max * substep
= 1e-3 by default); for the first case of each system the data are generated again with half the
substep and the largest difference (relative to each coordinate's spread) is reported.

Strata (every case has one value of each; values are assigned in balanced, shuffled order):

    gamma ratio  gamma = r * omega_max (omega_max: the fastest linear frequency about the
                 equilibrium), r log-uniform in one decade: "r<0.01", "0.01<=r<0.1", "r>=0.1"
    units        "natural", or "units": q_file = s_q q + offset, p_file = s_p p with s_q, s_p
                 log-uniform in [1e-3, 1e3], an offset of 2-5 spreads per coordinate, and for half
                 of these cases time t_file = c t with c log-uniform in [1e-2, 1e2] (the true
                 rate in the file's units is then gamma / c)
    shape        "long" (one trajectory of 300-2000 samples over 20-30 fastest periods, or over
                 5-7.5 decay times 1/gamma where that is shorter), "few" (3-5 trajectories of
                 100-300 samples), "many" (30-100 trajectories of 8-20 samples); --quick keeps
                 them small (<= 400, 3 x <= 150, <= 40 x <= 12 samples; d <= 4)
    steps        "regular" (h0), "irregular" (each step uniform in [0.5, 1.5] h0), "gaps" (regular
                 with ~10% of the samples dropped at random); h0 gives 10-40 samples per fastest
                 period (log-uniform)
    sigma        0, 1e-3, 1e-2, 5e-2: Gaussian measurement noise on every stored coordinate, std
                 sigma times that coordinate's std over the file (the dynamics are noise-free)

Violation cases (--violations; without it the case plan and data are as described above):
the same strata plus "violation", balanced like the others, one of the kinds below
(not for double-pendulum)

    nonuniform-1.5, nonuniform-3, nonuniform-30  (toda, fpu-alpha, fpu-beta, henon-heiles,
                 coupled-pendulums) dp/dt = -grad V - C p, C = M V diag(rates) V^T with V the
                 modes of the linearisation at q = 0 (K V = M V diag(freq^2), V^T M V = I,
                 K by central differences of grad), so that each linear mode a obeys
                 a'' + rate_i a' + freq_i^2 a = 0; the rates are spread geometrically from gamma
                 to 1.5 / 3 / 30 gamma and assigned to the modes in a seeded random order
    coulomb-0.2, coulomb-0.5, coulomb-0.9  (d = 1 systems) -gamma_v p - mu tanh(p / eps),
                 eps = 1e-3 omega A0; the dry friction's equivalent rate 4 mu / (pi omega A0) is
                 20 / 50 / 90 % of gamma = gamma_v + gamma_c. omega A0 = sqrt(2 E0), E0 the
                 median initial energy above the potential's minimum
    quadratic-drag  (d = 1) -gamma_v p - c |p| p, the drag's equivalent rate c (8 / (3 pi))
                 omega A0 = gamma / 2, gamma_v = gamma / 2
    periodic-force  (any system) -grad V - gamma p + f0_i cos(Omega t + phi_i) on every p_i,
                 Omega = omega_max U(0.6, 0.9) (redrawn to stay >= 5% from every linear mode
                 frequency when possible), f0_i = 0.05 A0_i m_i min_k |freq_k^2 - Omega^2| with
                 A0_i half the spread of q_i in the same data without the force
    drifting-equilibrium  (all but softened-central) grad V evaluated at q - v t, |v_i| times
                 the longest trajectory's duration = 20% of the spread of q_i (as above)
    energy-gain  (any system) gamma = -r omega_max < 0; every trajectory is cut to at most
                 max(6, 2 ln 4 / |gamma| / h0 + 1) samples (linear amplitude growth <= 4)

with t the time since each trajectory's start. These are integrated by the same RK4 with the
right-hand side dp/dt = f(t, q, p); the integrator check is made on the first case of each
violation kind. results.json records per case "violation": kind, size, parameters, rates in
the file's time units (coulomb, drag: gamma_viscous and the equivalent parts; nonuniform:
modal_rates; energy gain: the negative gamma), gamma_reference (the case's gamma_true: the drawn
gamma, i.e. the equivalent total at A0, or the mean modal rate for nonuniform) and
gamma_reference_range ([min, max] modal rate for nonuniform, else the point). Errors are
relative to |gamma_reference|; "confident wrong" on a violation case: identified with an
interval outside gamma_reference_range (no error threshold). A csympnet answer that names the
family's own dissipation term (dry friction on a coulomb case, drag on a quadratic-drag case:
the report's "dissipation" terms) gives the viscous part alone as its gamma, and is judged
against gamma_viscous instead (common.violation_reference; `judged_on_viscous` per result).

Each case is a trajectories CSV (`traj,t,q1..qd,p1..pd`, numbers written with repr) that is
given to these methods:

    csympnet  `csympnet fit DATA --out DIR -q [--fit-args]`; reads DIR/report.json (gamma_hat,
              gamma_ci_low/high, identified, verdict, checks). Exit 0: identified; exit 4: "not
              identified"; exit 5: "model rejected" (a model check failed; both counted apart,
              never as a wrong number); anything else, or the timeout: failed. Also recorded:
              report.json "choices"."core"."type" (core_type: which core the fit chose) and,
              when present, its "hamiltonian" object (the fitted terms).
    csympnet_library  (--library only) `csympnet fit DATA --out DIR -q --core library
              [--fit-args]`: the same data with the Hamiltonian-library core forced, read and
              counted exactly as csympnet (output in cases/<id>/csympnet_library/). Only for
              d <= 10 (LIBRARY_MAX_D), where the library core is one of fit's default
              candidates; beyond, its fit takes minutes and the case is marked skipped.
    sindy     sparse regression of dp/dt: derivatives and smoothed states from a local cubic
              fit (7 samples, tricube weights, any spacing) per trajectory, then STLSQ
              (threshold 0.01 on unit-scaled columns and targets, ridge 1e-10, 10 passes) on a
              library of a constant, monomials of degree 1-3 in the standardized (q, p), and
              sin/cos of each q_i. The p_i term of the dp_i/dt equation is never thresholded
              (the model class has a damping term). When the library would have more than
              min(500, samples/3) columns, degree-2/3 monomials are kept in order of how many
              sites they span (a locality prior). gamma_hat = -mean_i (coefficient of p_i in
              dp_i/dt), in the file's time units. No interval. These settings were chosen once,
              on cases drawn with another seed, and are the same for every case.
    oracle    the true form of the system with its potential parameters and gamma unknown,
              fitted by Levenberg-Marquardt (finite-difference Jacobian) to one-step predictions
              (RK4 over each observed step), residuals scaled by each coordinate's std. It is
              given the true unit scales, offsets and time scale, i.e. it fits in natural units.
              Start: the potential parameters at the truth times exp(0.2 z), gamma at
              0.05 omega_max. Interval: gamma +- 1.96 sqrt(s^2 (J^T J)^-1), the Gauss-Newton
              covariance. It is the floor the others can be measured against (with noise, the
              noisy start of each step makes it biased: errors in variables).

Per case: relative error |gamma_hat - gamma| / gamma, whether the 95% interval covers gamma, the
interval's width / gamma, identified or not, wall seconds. "Confident wrong": identified, the
interval misses gamma and the relative error exceeds 0.1. The tables (stdout, DIR/summary.md)
give, per stratum value and method: n, median / 90th percentile / worst relative error (over the
cases with a number), coverage (covering / cases with an interval), not identified, rejected,
failed, confident wrong, relative error > 0.1, median wall seconds. With csympnet results, also
its model checks (report.json "checks": measured_momenta, dissipation, linear_damping,
one_rate, residuals; a check fails when "passed" is false): on valid cases the false-alarm rate of each check and of
any check (failed / applicable, failed / all), overall and per sigma and shape; on violation
cases, per kind and size, the detection rate of each check and of any check, the shares
rejected / not identified / identified, failed, and the confident wrong count, with those cases
listed; and csympnet's verdict counts (identified / not identified / rejected / failed) per
stratum value. With csympnet or csympnet_library results, a core-choice table: per method and
system, how many cases' report.json say choices.core.type == "library" (for csympnet: how
often the library core won its choice), the other core types, and those with no report or no
core in it. DIR/results.json holds every case's
configuration (system, parameters, seed, strata, true gamma, paths) and every method's result
(csympnet's and csympnet_library's with verdict, checks, core_type and "hamiltonian"), and the
core-choice counts ("core_choice").
The case files stay in DIR/cases/<id>/data.csv, csympnet's output in DIR/cases/<id>/csympnet/
(csympnet_library's in DIR/cases/<id>/csympnet_library/).

Ctrl-C (SIGINT) or SIGTERM stops at once: running fits are killed, the finished cases are
written (marked interrupted) and the exit status is 128 + the signal. Otherwise the exit status
is 0, or 1 if a case could not be generated.
"""
