"""csympnet.fit, fit_trajectories and run: results, options, and agreement with the CLI."""

import functools
import json
import os
import signal
import threading
import time
import warnings

import numpy as np
import pytest

import csympnet
from conftest import EPOCHS


def test_fit_identifies_gamma_on_s1(s1_pairs):
    model = csympnet.fit(*s1_pairs, epochs=2000)
    assert model.type == "csympnet" and model.d == 1 and model.n_params == 115
    assert abs(model.gamma - 0.05) < 5e-3  # γ = 0.05; the paper's budget gets ~1e-6
    t = model.training
    assert t["epochs_run"] == 2000 and t["stop_reason"] == "budget"
    assert 0 <= t["best_epoch"] <= 2000 and t["best_val_loss"] < 1e-6


def test_fit_defaults_are_the_librarys_identification_recipe():
    """csympnet.fit's signature shows the defaults of FitConfig::identification()."""
    import inspect
    from csympnet import _core
    recipe = json.loads(_core.fit_recipe_json())
    d = {k: p.default for k, p in inspect.signature(csympnet.fit).parameters.items()}
    train = recipe["train"]
    assert d["model"] == recipe["model"]
    assert d["seed"] == recipe["seed"]
    assert d["val_fraction"] == recipe["val_fraction"]
    assert d["beta_init"] == recipe["beta_init"]
    assert d["warm_start"] == recipe["warm_start"]
    assert d["lr"] == train["adamw"]["lr"]
    assert d["weight_decay"] == train["adamw"]["weight_decay"]
    assert d["beta_decay"] == train["adamw"]["decay_damping"]
    assert d["lr_schedule"] == train["lr_schedule"]
    assert d["lr_final_fraction"] == train["lr_final_fraction"]
    assert d["val_every"] == train["val_every"]
    assert train["epochs"] == 0 and d["epochs"] is None  # by dimension
    assert d["refine"] == recipe["refine"]["method"] == "auto"
    assert d["bootstrap"] is None and recipe["bootstrap"]["replicates"] == "auto"
    assert d["refine_iterations"] is None and d["refine_solver"] is None


def test_sympnet_has_no_gamma(s1_pairs):
    model = csympnet.fit(*s1_pairs, model="sympnet", epochs=50)
    assert model.type == "sympnet" and model.gamma is None and model.n_params == 114


def test_fit_claims_no_interval_and_says_where_one_comes_from(s1_model):
    assert s1_model.gamma is not None and s1_model.gamma_interval is None
    assert "identify" in s1_model.meta["gamma_interval_note"]


def test_fit_warns_on_states_far_from_order_one(s1_pairs):
    z0, z1, h = s1_pairs
    with pytest.warns(UserWarning, match="of order"):
        model = csympnet.fit(z0 * 1e-9, z1 * 1e-9, h, epochs=20, refine="none")
    assert model.gamma_interval is None and "warnings" in model.meta


def test_fit_equals_cli_fit_bit_for_bit(tmp_path, run_cli, s1_pairs):
    path = tmp_path / "pairs.csv"
    csympnet.write_csv(path, s1_pairs)
    run_cli("fit", path, "--recipe", "classic", "--epochs", EPOCHS, "--seed", 7,
            "--out", tmp_path / "out", "-q")
    cli_model = csympnet.load(tmp_path / "out" / "model.json")
    py_model = csympnet.fit(*s1_pairs, epochs=EPOCHS, seed=7)
    assert np.array_equal(py_model.params, cli_model.params)
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    assert report["gamma_hat"] == py_model.gamma


def test_options_change_the_fit(s1_pairs):
    # The bootstrap interval does not touch the parameters compared here; it is left out.
    fit = functools.partial(csympnet.fit, bootstrap=0)
    base = fit(*s1_pairs, epochs=100)
    for kwargs in ({"seed": 1}, {"lr": 2e-3}, {"lr_schedule": "constant"}, {"warm_start": False},
                   {"beta_decay": False}, {"core": "la:2:3"}, {"weight_decay": 0.0},
                   {"refine": "none"}):
        other = fit(*s1_pairs, epochs=100, **kwargs)
        assert other.n_params != base.n_params or not np.array_equal(other.params, base.params), kwargs
    # beta_init is the start only without the warm start.
    cold = fit(*s1_pairs, epochs=100, warm_start=False)
    assert not np.array_equal(
        fit(*s1_pairs, epochs=100, warm_start=False, beta_init=-0.2).params, cold.params)
    assert np.array_equal(fit(*s1_pairs, epochs=100, beta_init=-0.2).params, base.params)
    assert fit(*s1_pairs, epochs=10, core="g:2:4").hyperparams["core"] == {
        "type": "g", "layers": 2, "width": 4}
    assert fit(*s1_pairs, epochs=10, core={"type": "la", "layers": 2, "sublayers": 3}
               ).n_params == fit(*s1_pairs, epochs=10, core="la:2:3").n_params
    # Step polynomials: one coefficient per linear sublayer (2 x 3) and activation module (1).
    poly = fit(*s1_pairs, epochs=10, core="la:2:3:h2")
    assert poly.hyperparams["core"]["step_terms"] == 2
    assert poly.n_params == fit(*s1_pairs, epochs=10, core="la:2:3").n_params + 7
    for bad in ("g:2:4:h2", "la:2:3:h3"):
        with pytest.raises(ValueError, match="h2"):
            fit(*s1_pairs, epochs=10, core=bad)


def test_explicit_validation_set(s1_pairs):
    val = csympnet.generate("s1", "val")
    model = csympnet.fit(*s1_pairs, epochs=50, validation=val, bootstrap=0)
    assert model.meta["pairs_train"] == 80 and model.meta["pairs_val"] == 20
    split = csympnet.fit(*s1_pairs, epochs=50, bootstrap=0)
    assert split.meta["pairs_train"] == 64 and split.meta["pairs_val"] == 16


def test_scalar_h_means_one_step_for_all(s1_pairs):
    z0 = s1_pairs.z0
    z1 = csympnet.System.preset("s1").flow(z0, 0.1)
    a = csympnet.fit(z0, z1, 0.1, epochs=20)
    b = csympnet.fit(z0, z1, np.full(len(z0), 0.1), epochs=20)
    assert np.array_equal(a.params, b.params)


def test_progress_callback_sees_training_and_can_stop(s1_pairs):
    seen = []
    csympnet.fit(*s1_pairs, epochs=100, val_every=20, refine="lm", refine_iterations=30,
                 bootstrap=0, progress=seen.append)
    adamw = [p for p in seen if p["stage"] == "adamw"]
    assert [p["epoch"] for p in adamw] == [20, 40, 60, 80, 100]
    assert all(p["epochs"] == 100 and p["gamma"] > 0 for p in adamw)
    # The second stage reports through the same callback, after AdamW, in its own stage.
    lm = seen[len(adamw):]
    assert lm and all(p["stage"] == "lm" and p["epochs"] == 30 for p in lm)
    assert all(a["epoch"] < b["epoch"] for a, b in zip(lm, lm[1:]))
    assert all(b["best_val_loss"] <= a["best_val_loss"] for a, b in zip(lm, lm[1:]))
    # The bootstrap reports each replicate, with its γ̂ and no losses.
    seen = []
    csympnet.fit(*s1_pairs, epochs=50, refine="lm", refine_iterations=5, bootstrap=10,
                 progress=seen.append)
    boot = [p for p in seen if p["stage"] == "bootstrap"]
    assert [p["epoch"] for p in boot] == list(range(1, 11))
    assert all(p["epochs"] == 10 and p["gamma"] > 0 and p["val_loss"] is None for p in boot)
    stopped = csympnet.fit(*s1_pairs, epochs=1000, progress=lambda p: p["epoch"] < 30)
    assert stopped.training["stop_reason"] == "callback" and stopped.training["epochs_run"] == 30


def test_progress_callback_exception_propagates(s1_pairs):
    def boom(p):
        raise KeyError("from the callback")

    with pytest.raises(KeyError, match="from the callback"):
        csympnet.fit(*s1_pairs, epochs=100, progress=boom)


def test_training_releases_the_gil(s1_pairs):
    # A Python thread keeps counting while fit() trains; with the GIL held it would get only
    # the odd 5 ms switch slice. Its rate alone (main thread asleep) is the yardstick. And the
    # fit beside it is not much slower than alone: taking the GIL back to look for Ctrl-C waits
    # for the busy thread's switch interval, which, done every 2 ms, once made it 10-30 times
    # slower.
    t0 = time.perf_counter()
    csympnet.fit(*s1_pairs, epochs=20000, val_every=20000)
    alone = time.perf_counter() - t0
    done = threading.Event()
    count = [0]

    def spin():
        while not done.is_set():
            count[0] += 1

    thread = threading.Thread(target=spin)
    thread.start()
    before = count[0]
    time.sleep(0.2)
    rate = (count[0] - before) / 0.2
    before = count[0]
    t0 = time.perf_counter()
    csympnet.fit(*s1_pairs, epochs=20000, val_every=20000)
    elapsed = time.perf_counter() - t0
    during = count[0] - before
    done.set()
    thread.join()
    assert elapsed > 0.15  # long enough to tell
    assert during > 0.25 * rate * elapsed, f"{during} increments in {elapsed:.2f} s; alone {rate:.0f}/s"
    assert elapsed < 4.0 * alone + 0.5, f"{elapsed:.2f} s beside a busy thread, {alone:.2f} s alone"


def test_ctrl_c_stops_training(s1_pairs):
    timer = threading.Timer(0.2, os.kill, (os.getpid(), signal.SIGINT))
    t0 = time.perf_counter()
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        csympnet.fit(*s1_pairs, epochs=1_000_000)  # ~25 s if not interrupted
    timer.join()
    assert time.perf_counter() - t0 < 5.0


def _trajectories(n=3, steps=12):
    system = csympnet.System(kind="cubic", d=2, gamma=0.1, alpha=0.05)
    rng = np.random.default_rng(3)
    trajs = []
    for _ in range(n):
        t = np.cumsum(np.r_[0.0, rng.uniform(0.05, 0.15, steps)])
        z = [rng.uniform(-1, 1, 4)]
        for h in np.diff(t):
            z.append(system.flow(z[-1], h))
        trajs.append(csympnet.Trajectory(t, np.array(z)))
    return trajs


def test_fit_trajectories_equals_cli_fit_of_the_csv(tmp_path, run_cli):
    trajs = _trajectories()
    path = tmp_path / "traj.csv"
    csympnet.write_csv(path, trajs)
    run_cli("fit", path, "--recipe", "classic", "--epochs", 100, "--bootstrap", 0,
            "--out", tmp_path / "out", "-q")
    cli_model = csympnet.load(tmp_path / "out" / "model.json")
    t = [tr.t for tr in trajs]
    z = [tr.z for tr in trajs]
    py_model = csympnet.fit_trajectories(z, t, epochs=100, bootstrap=0)
    assert np.array_equal(py_model.params, cli_model.params)


def test_identification_options_equal_cli_fit_bit_for_bit(tmp_path, run_cli):
    # Warm start, LM and a trajectory bootstrap, as `csympnet fit` runs them from the CSV.
    trajs = _trajectories(n=6, steps=12)
    path = tmp_path / "traj.csv"
    csympnet.write_csv(path, trajs)
    run_cli("fit", path, "--recipe", "classic", "--epochs", 200, "--warm-start", "--refine", "lm",
            "--refine-iterations", 20, "--bootstrap", 10, "--core", "la:3:4:h2",
            "--out", tmp_path / "out", "-q")
    cli_model = csympnet.load(tmp_path / "out" / "model.json")
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    py_model = csympnet.fit_trajectories([tr.z for tr in trajs], [tr.t for tr in trajs],
                                         epochs=200, warm_start=True, refine="lm",
                                         refine_iterations=20, bootstrap=10, core="la:3:4:h2")
    assert np.array_equal(py_model.params, cli_model.params)
    assert report["gamma_hat"] == py_model.gamma
    assert report["bootstrap"]["resample"] == "trajectories"
    # A training recipe claims no interval: the bootstrap asked for is a spread, in meta.
    assert py_model.gamma_interval is None
    assert report["gamma_ci_low"] is None and report["gamma_ci_high"] is None
    assert py_model.meta["bootstrap"]["low"] == report["bootstrap"]["low"]
    assert py_model.meta["bootstrap"]["high"] == report["bootstrap"]["high"]
    assert "csympnet fit" in py_model.meta["gamma_interval_note"]


def test_identification_options_are_checked(s1_pairs):
    for kwargs, exc, match in (({"refine": "newton"}, ValueError, "refine"),
                               ({"refine_iterations": 0}, ValueError, "refine_iterations"),
                               ({"refine_solver": "svd", "refine": "lm"}, ValueError, "refine_solver"),
                               ({"refine_solver": "dense_qr"}, ValueError, "refine_solver"),
                               ({"bootstrap": -1}, ValueError, "bootstrap"),
                               ({"warm_start": 1}, TypeError, "warm_start")):
        with pytest.raises(exc, match=match):
            csympnet.fit(*s1_pairs, epochs=10, **kwargs)


def test_threads_give_the_same_bits():
    # d = 10 pairs: CSympNet-ID's epochs then run on a team of threads (docs/architecture.md).
    z0, z1, h = csympnet.generate("s2", "train")
    one = csympnet.fit(z0, z1, h, epochs=30, refine="none", bootstrap=0)
    two = csympnet.fit(z0, z1, h, epochs=30, refine="none", bootstrap=0, threads=2)
    assert np.array_equal(one.params, two.params)
    a = csympnet.run("s3", epochs=20)
    b = csympnet.run("s3", epochs=20, threads=2)
    assert np.array_equal(a.model.params, b.model.params)
    assert b.report["train_threads"] == 2 and "train_threads" not in a.report
    for bad in (0, -1, 257):
        with pytest.raises(ValueError, match="threads"):
            csympnet.fit(z0, z1, h, epochs=1, threads=bad)
        with pytest.raises(ValueError, match="threads"):
            csympnet.run("s3", epochs=1, threads=bad)
    with pytest.raises(TypeError, match="threads"):
        csympnet.run("s3", epochs=1, threads=1.5)


def test_chunks_and_mini_batches_equal_the_cli_and_ignore_threads(tmp_path, run_cli):
    # 400 s2 pairs (320 train) in chunks of 64 and mini-batches of 100: the chunks' sums follow
    # one fixed tree, so threads do not change the bits; Python and `csympnet fit --recipe classic` agree.
    pairs = csympnet.generate("s2", "train")
    z0, z1, h = pairs
    kw = dict(epochs=4, val_every=2, refine="none", bootstrap=0, chunk_pairs=64,
              batch_size=100)
    one = csympnet.fit(z0, z1, h, **kw)
    two = csympnet.fit(z0, z1, h, threads=2, **kw)
    assert np.array_equal(one.params, two.params)
    whole = csympnet.fit(z0, z1, h, epochs=4, val_every=2, refine="none", bootstrap=0)
    assert not np.array_equal(one.params, whole.params)
    path = tmp_path / "pairs.csv"
    csympnet.write_csv(path, pairs)
    run_cli("fit", path, "--recipe", "classic", "--epochs", 4, "--val-every", 2, "--refine",
            "none", "--bootstrap", 0, "--chunk-pairs", 64, "--batch-size", 100, "--out",
            tmp_path / "out", "-q")
    cli_model = csympnet.load(tmp_path / "out" / "model.json")
    assert np.array_equal(cli_model.params, one.params)


def test_fit_trajectories_forms_agree():
    trajs = _trajectories(steps=10)
    lists = csympnet.fit_trajectories([tr.z for tr in trajs], [tr.t for tr in trajs], epochs=20, bootstrap=0)
    labels = np.repeat([5, 2, 9], 11)
    flat = csympnet.fit_trajectories(np.concatenate([tr.z for tr in trajs]),
                                     np.concatenate([tr.t for tr in trajs]), traj=labels, epochs=20, bootstrap=0)
    stacked = csympnet.fit_trajectories(np.stack([tr.z for tr in trajs]),
                                        np.stack([tr.t for tr in trajs]), epochs=20, bootstrap=0)
    assert np.array_equal(lists.params, flat.params)
    assert np.array_equal(lists.params, stacked.params)
    # Pairs never span two trajectories: 3 trajectories of 10 steps give 30 pairs.
    assert lists.meta["pairs_train"] + lists.meta["pairs_val"] == 30


def test_fit_trajectories_single_and_pairs_equivalence():
    tr = _trajectories(n=1)[0]
    a = csympnet.fit_trajectories(tr.z, tr.t, epochs=20, bootstrap=0)
    b = csympnet.fit(tr.z[:-1], tr.z[1:], np.diff(tr.t), epochs=20, bootstrap=0)
    assert np.array_equal(a.params, b.params)


def test_fit_trajectories_old_argument_order_is_swapped_with_a_warning():
    # States first since identify(z, t) and CSympNetID.fit(x, t) take them so; (t, z) is
    # told apart by dimensions (times have one fewer) in every form, and gives the same fit.
    trajs = _trajectories(steps=10)
    zs, ts = [tr.z for tr in trajs], [tr.t for tr in trajs]
    for z, t in ((zs, ts), (zs[0], ts[0]), (np.stack(zs), np.stack(ts)), (np.stack(zs), ts[0])):
        with pytest.warns(FutureWarning, match=r"takes \(z, t\)"):
            old = csympnet.fit_trajectories(t, z, epochs=20, bootstrap=0)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            now = csympnet.fit_trajectories(z, t, epochs=20, bootstrap=0)
        assert np.array_equal(old.params, now.params)


def test_run_equals_cli_run(tmp_path, run_cli):
    result = csympnet.run("s1", epochs=200, seed=5)
    run_cli("run", "--preset", "s1", "--epochs", 200, "--seed", 5, "--out", tmp_path, "-q")
    report = json.loads((tmp_path / "report.json").read_text())
    for key in ("gamma_hat", "l2_error", "residual_mean", "structure_residual_max", "best_val_loss"):
        assert result.report[key] == report[key], key
    assert np.array_equal(result.model.params, csympnet.load(tmp_path / "model.json").params)
    assert len(result.rollouts) == len(result.tests) == 10
    assert result.rollouts[0].shape == result.tests[0].z.shape == (51, 2)


def test_run_trains_a_baseline():
    result = csympnet.run("s1", "dhnn2", epochs=20)
    assert result.model.type == "dhnn2" and result.model.gamma is not None
    assert result.report["model"] == "dhnn2" and np.isfinite(result.report["l2_error"])


# Every stage after AdamW stops within a second of Ctrl-C with KeyboardInterrupt: Ceres' LM,
# csympnet's own LM (its normal equations taken in polled row blocks at 4,111 parameters),
# L-BFGS, the bootstrap, and the identification recipe's LM. Each budget would run for minutes.
_STAGES = {
    "ceres_lm": dict(core="g:2:8", epochs=5, refine="lm", refine_solver="dense_qr",
                     refine_iterations=10**8, bootstrap=0),
    "blas_lm": dict(epochs=5, refine="lm", refine_solver="blas_normal_cholesky",
                    refine_iterations=10**8, bootstrap=0),
    "lbfgs": dict(core="g:2:8", epochs=5, refine="lbfgs", refine_iterations=10**8, bootstrap=0),
    "bootstrap": dict(core="g:2:8", epochs=5, refine="lm", refine_iterations=2,
                      bootstrap=10**6),
}


@pytest.fixture(scope="module")
def noisy_d10_pairs():
    return csympnet.generate("s2", "train", n=400, sigma=0.01)


def _interrupt_after(delay, call):
    """Runs call() in this (the main) thread, sends SIGINT after `delay` s, and returns the
    seconds from the signal to the KeyboardInterrupt."""
    sent = []

    def send():
        sent.append(time.perf_counter())
        os.kill(os.getpid(), signal.SIGINT)

    timer = threading.Timer(delay, send)
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        call()
    caught = time.perf_counter()
    timer.join()
    assert sent, "the call ended before the signal"
    return caught - sent[0]


@pytest.mark.parametrize("stage", sorted(_STAGES))
def test_ctrl_c_stops_every_later_stage_within_a_second(noisy_d10_pairs, stage):
    latency = _interrupt_after(1.5, lambda: csympnet.fit(*noisy_d10_pairs, **_STAGES[stage]))
    assert latency < 1.0, f"{stage}: KeyboardInterrupt {latency:.2f} s after SIGINT"


def test_ctrl_c_stops_identify_within_a_second(noisy_d10_pairs):
    z0, z1, h = noisy_d10_pairs
    latency = _interrupt_after(
        4.0, lambda: csympnet.identify(pairs=(z0, z1, h), epochs=50, lm_iterations=100000))
    assert latency < 1.0, f"KeyboardInterrupt {latency:.2f} s after SIGINT"


def test_verbose_draws_bars_for_every_stage_and_keeps_the_callback(s1_pairs, capsys):
    seen = []
    csympnet.fit(*s1_pairs, epochs=40, refine="lm", refine_iterations=5, bootstrap=10,
                 verbose=True, progress=seen.append)
    err = capsys.readouterr().err
    assert "AdamW" in err and "LM" in err and "bootstrap" in err
    assert {p["stage"] for p in seen} == {"adamw", "lm", "bootstrap"}
    with pytest.raises(TypeError, match="verbose: expected True or False"):
        csympnet.fit(*s1_pairs, epochs=5, verbose="yes")
