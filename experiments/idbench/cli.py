"""The command line: options, the plan, the worker pool, Ctrl-C, the outputs."""
import argparse
import concurrent.futures as cf
import datetime
import os
import platform
import shlex
import shutil
import signal
import subprocess
import sys
import time

from .common import GEN_OMEGA_DT, METHODS, REPO, STOP, Interrupted
from .forced import FORCED_EXTRA_SYSTEMS, FORCED_SYSTEMS, plan_forced
from .forced_plan import FORCED_METHODS, run_forced_case
from .forced_tables import case_rms, write_forced_outputs
from .friction import FRICTION_STRATA, plan_friction
from .friction_plan import FRICTION_METHODS, run_friction_case
from .friction_tables import write_friction_outputs
from .generate import plan, plan_violations
from .observed import OBSERVED_METHODS, OBSERVED_STRATA, plan_observed, run_observed_case
from .observed_tables import write_observed_outputs
from .peers.csympnet import CHILDREN, CHILDREN_LOCK, kill_group
from .peers.oracle import ORACLE_OMEGA_DT
from .peers.sindy import LIBRARY_CAP, SG_DEGREE, SG_WINDOW, STLSQ_RIDGE, STLSQ_THRESHOLD
from .runner import run_case
from .systems import DEFAULT_SYSTEMS, EXTRA_SYSTEMS, SYSTEM_NAMES
from .tables import write_outputs

def csympnet_version(exe):
    try:
        r = subprocess.run([exe, "--version"], capture_output=True, text=True, timeout=30)
        text = (r.stdout.strip() or r.stderr.strip()).splitlines()
        return text[0] if r.returncode == 0 and text else "n/a"
    except (OSError, subprocess.TimeoutExpired):
        return "n/a"


def uname():
    try:
        return subprocess.run(["uname", "-a"], capture_output=True, text=True).stdout.strip()
    except OSError:
        return " ".join(platform.uname())


def progress(i, n, c):
    parts = []
    for m in METHODS:
        r = c["methods"].get(m)
        if r is None or r.get("status") == "skipped":
            continue
        if r.get("status") == "ok":
            parts.append(f"{m} {r['rel_err']:.1e}")
        elif r.get("status") == "rejected":
            parts.append(f"{m} rejected")
        else:
            parts.append(f"{m} {r.get('status')}")
    print(f"[{i}/{n}] {c['id']} d={c['d']} {c['strata']['ratio']} {c['strata']['units']} "
          f"{c['strata']['shape']} {c['strata']['steps']} sigma={c['strata']['sigma']:g}: "
          + ", ".join(parts), file=sys.stderr, flush=True)


def _gamma_parts(c, methods, extra=lambda r: ""):
    """each method's progress: its relative error of gamma, whether its interval covers, what
    `extra` adds, and its CPU seconds; or its status"""
    parts = []
    for m in methods:
        r = c["methods"].get(m)
        if r is None or r.get("status") == "skipped":
            continue
        cpu = r.get("cpu_seconds")
        cpu = "" if cpu is None else f" {cpu:.1f} CPU s"
        if r.get("status") == "ok":
            cov = {True: ", covers", False: ", misses"}.get(r.get("covers"), "")
            parts.append(f"{m} {r['rel_err']:.1e}{cov}{extra(r)}{cpu}")
        else:
            parts.append(f"{m} {r.get('status')}{cpu}")
    return parts


def progress_observed(i, n, c):
    parts = _gamma_parts(c, OBSERVED_METHODS)
    print(f"[{i}/{n}] {c['id']} d={c['d']} samples={c['samples']}: " + ", ".join(parts),
          file=sys.stderr, flush=True)


def progress_forced(i, n, c):
    parts = []
    for m in FORCED_METHODS:
        r = c["methods"].get(m)
        if r is None or r.get("status") == "skipped":
            continue
        ms, ri = case_rms(c, m, "test-multisine"), case_rms(c, m, "test-rising")
        g = f" gamma {r['gamma_hat']:.4g}" if r.get("gamma_hat") is not None else ""
        cov = {True: " covers", False: " misses"}.get(r.get("covers"), "")
        rms = "" if ms is None else f" rms {ms:.2e}/{ri:.2e}"
        parts.append(f"{m} {r.get('status')}{g}{cov}{rms}")
    print(f"[{i}/{n}] {c['id']} d={c['d']} sigma={c['sigma']:.1e}: " + ", ".join(parts),
          file=sys.stderr, flush=True)


def progress_friction(i, n, c):
    def rate_and_kinds(r):
        rate = r.get("rate_rel_err")
        rate = "" if rate is None else f", rate {rate:.1e}"
        return rate + (f" [{','.join(r['kinds']) or 'viscous'}]" if "kinds" in r else "")
    parts = _gamma_parts(c, FRICTION_METHODS, rate_and_kinds)
    print(f"[{i}/{n}] {c['id']}: " + ", ".join(parts), file=sys.stderr, flush=True)


def parse_args():
    """The parser (main reports its own checks through it) and the parsed options."""
    ap = argparse.ArgumentParser(
        description="Identification benchmark of the damping rate: csympnet fit against a "
                    "SINDy-style regression and a parametric oracle.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="See experiments/idbench/__init__.py for the systems, strata and peers.")
    ap.add_argument("--out", required=True, help="output directory")
    ap.add_argument("--cases", type=int, default=None,
                    help="number of cases (default 120, 8 with --quick; with --violations 60, "
                         "10 with --quick)")
    ap.add_argument("--violations", action="store_true",
                    help="run only violation cases (data that break one assumption)")
    ap.add_argument("--quick", action="store_true", help="a small subset of small cases")
    ap.add_argument("--seed", type=int, default=1, help="default 1")
    ap.add_argument("--only-peers", action="store_true",
                    help="skip csympnet (and csympnet_library)")
    ap.add_argument("--systems", default=None,
                    help="comma-separated subset of: " + ",".join(SYSTEM_NAMES)
                         + ', or "all" (default: all but ' + ",".join(EXTRA_SYSTEMS) + ")")
    ap.add_argument("--csympnet", default=os.path.join(REPO, "build", "bin", "csympnet"))
    ap.add_argument("--fit-args", default="",
                    help='extra options for every `csympnet fit`, e.g. --fit-args="--epochs 2000"')
    ap.add_argument("--timeout", type=float, default=600.0, help="seconds per fit (default 600)")
    ap.add_argument("--jobs", type=int, default=1, help="cases in parallel (default 1)")
    ap.add_argument("--momenta", choices=["given", "gradient", "savgol"], default="given",
                    help="p columns as generated (given, default), or computed from the noisy q "
                         "as a user without a momentum sensor would: numpy.gradient or a "
                         "Savitzky-Golay derivative (window 11, cubic)")
    ap.add_argument("--observed", action="store_true",
                    help="also fit every case from its positions alone (csympnet_positions) and "
                         "with p from centred differences of the noisy q "
                         "(csympnet_differenced), side by side with the given p")
    ap.add_argument("--library", action="store_true",
                    help="also fit every case with the Hamiltonian-library core forced "
                         "(`--core library`): method csympnet_library")
    ap.add_argument("--skip-peers", action="store_true",
                    help="skip the SINDy-style peer and the oracle (csympnet alone; "
                         "csympnet_library still runs with --library)")
    ap.add_argument("--observed-plan", action="store_true",
                    help="run the observed-records plan instead (linear records in pixels, "
                         "oversampled, 10^5 samples, encoder counts, decays into the noise; "
                         "csympnet beside the oracle, the textbook fits and sindy, with CPU "
                         "seconds): --cases in all (default 10, 5 with --quick), the strata "
                         "taken in turn")
    ap.add_argument("--observed-strata", default=",".join(OBSERVED_STRATA),
                    help="with --observed-plan: a comma-separated subset of "
                         + ",".join(OBSERVED_STRATA))
    ap.add_argument("--with-momenta", action="store_true",
                    help="with --observed-plan: also fit each linear record with measured "
                         "momenta (csympnet_with_p), for the CPU cost of positions only")
    ap.add_argument("--forced-plan", action="store_true",
                    help="run the forced-records plan instead (driven Duffing, pendulum and "
                         "2-dof Duffing chain; multisine and rising-amplitude tests; linear ARX, "
                         "polynomial NARX and the oracle beside csympnet): --cases in all "
                         "(default 6, 3 with --quick), the systems taken in turn")
    ap.add_argument("--forced-systems", default=",".join(FORCED_SYSTEMS),
                    help="with --forced-plan: a comma-separated subset of "
                         + ",".join(FORCED_SYSTEMS + FORCED_EXTRA_SYSTEMS) + " (the last "
                         "outside csympnet's term library, only when named)")
    ap.add_argument("--friction-plan", action="store_true",
                    help="run the friction plan instead (viscous, Coulomb and drag decays, "
                         "an encoder-read pendulum with dry friction: idbench/friction.py), "
                         "csympnet beside the oracle and the envelope fit")
    ap.add_argument("--friction-strata", default=",".join(FRICTION_STRATA),
                    help="with --friction-plan: a comma-separated subset of "
                         + ",".join(FRICTION_STRATA))
    ap.add_argument("--force", action="store_true",
                    help="write into a non-empty --out (its cases/ folder is replaced)")
    return ap, ap.parse_args()


def _subset(ap, text, known, what):
    """the comma-separated names of `text`, each one of `known` (else a usage error)"""
    names = [x.strip() for x in text.split(",") if x.strip()]
    bad = [x for x in names if x not in known]
    if bad or not names:
        ap.error(f"unknown {what} {bad}; choose from {','.join(known)}")
    return names


def plan_size(ap, args):
    """The plan's number of cases (--cases, else the plan's default) and its subset (strata or
    systems; None for the main and violation plans); one plan at most."""
    if sum(map(bool, (args.forced_plan, args.observed_plan, args.friction_plan,
                      args.violations))) > 1:
        ap.error("--forced-plan, --observed-plan, --friction-plan and --violations are plans "
                 "of their own: give one")
    if args.with_momenta and not args.observed_plan:
        ap.error("--with-momenta: needs --observed-plan")
    default, subset = (8, 120), None
    if args.friction_plan:
        default = (5, 20)
        subset = _subset(ap, args.friction_strata, FRICTION_STRATA, "friction strata")
    elif args.forced_plan:
        default = (3, 6)
        subset = _subset(ap, args.forced_systems, FORCED_SYSTEMS + FORCED_EXTRA_SYSTEMS,
                         "forced systems")
    elif args.observed_plan:
        default = (5, 10)
        subset = _subset(ap, args.observed_strata, OBSERVED_STRATA, "observed strata")
    elif args.violations:
        default = (10, 60)
    n = args.cases if args.cases is not None else default[0 if args.quick else 1]
    if n < 1:
        ap.error("--cases must be >= 1")
    return n, subset


def main():
    ap, args = parse_args()
    if args.seed < 0:
        ap.error("--seed must be >= 0")
    if args.jobs < 1:
        ap.error("--jobs must be >= 1")
    n, subset = plan_size(ap, args)
    systems = DEFAULT_SYSTEMS
    if args.systems and args.systems.strip() == "all":
        systems = SYSTEM_NAMES
    elif args.systems:
        systems = [x.strip() for x in args.systems.split(",") if x.strip()]
        bad = [x for x in systems if x not in SYSTEM_NAMES]
        if bad or not systems:
            ap.error(f"unknown systems {bad}; choose from {','.join(SYSTEM_NAMES)}")
    try:
        extra = shlex.split(args.fit_args)
    except ValueError as e:
        ap.error(f"--fit-args: {e}")
    exe = os.path.abspath(args.csympnet)
    if not args.only_peers and not os.access(exe, os.X_OK):
        ap.error(f"no csympnet executable at {exe} (build it, give --csympnet, or --only-peers)")
    if os.path.isdir(args.out) and os.listdir(args.out) and not args.force:
        ap.error(f"{args.out} is not empty (give --force to reuse it)")
    args.out = os.path.abspath(args.out)
    os.makedirs(args.out, exist_ok=True)
    if os.path.isdir(os.path.join(args.out, "cases")):
        shutil.rmtree(os.path.join(args.out, "cases"))
    meta = {"command": shlex.join([sys.executable] + sys.argv),
            "date": datetime.datetime.now().astimezone().isoformat(timespec="seconds"),
            "uname": uname(),
            "csympnet": None if args.only_peers else exe,
            "csympnet_version": ("skipped (--only-peers)" if args.only_peers
                                 else csympnet_version(exe)),
            "seed": args.seed, "quick": args.quick, "violations": args.violations,
            "fit_args": extra, "timeout": args.timeout, "momenta": args.momenta,
            "observed": args.observed, "skip_peers": args.skip_peers, "library": args.library,
            "systems": list(systems),
            "settings": {"gen_omega_dt": GEN_OMEGA_DT, "oracle_omega_dt": ORACLE_OMEGA_DT,
                         "sg_window": SG_WINDOW, "sg_degree": SG_DEGREE,
                         "stlsq_threshold": STLSQ_THRESHOLD, "stlsq_ridge": STLSQ_RIDGE,
                         "library_cap": LIBRARY_CAP}}
    run, write = None, write_outputs
    if args.friction_plan:
        meta.update(friction_plan=True, friction_strata=subset)
        cases = plan_friction(n, args.seed, subset)
        run, write = run_friction_case, write_friction_outputs
    elif args.forced_plan:
        meta.update(forced_plan=True, forced_systems=subset)
        cases = plan_forced(n, args.seed, subset)
        run, write = run_forced_case, write_forced_outputs
    elif args.observed_plan:
        meta.update(observed_plan=True, observed_strata=subset)
        cases = plan_observed(n, args.seed, subset)
        run, write = run_observed_case, write_observed_outputs
    elif args.violations:
        try:
            cases = plan_violations(n, args.seed, systems)
        except ValueError as e:
            ap.error(str(e))
    else:
        cases = plan(n, args.seed, systems)
    first = {}
    for c in cases:  # the integrator check: first case of each system (violation kind)
        first.setdefault(c["strata"]["violation"] if args.violations
                         else c.get("system", c.get("stratum")), c["index"])
    checked = set(first.values())

    got = {"signal": signal.SIGINT}

    def on_signal(signum, frame):
        got["signal"] = signum
        raise KeyboardInterrupt()
    # installed explicitly: a shell starts background jobs with SIGINT ignored
    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    pool = cf.ThreadPoolExecutor(max_workers=args.jobs)
    if run is None:
        futures = {pool.submit(run_case, c, args, c["index"] in checked, exe, extra): c
                   for c in cases}
    else:
        futures = {pool.submit(run, c, args, exe, extra): c for c in cases}
    pending = set(futures)
    done_count = 0
    try:
        while pending:
            finished, pending = cf.wait(pending, timeout=0.5, return_when=cf.FIRST_COMPLETED)
            for f in finished:
                c = futures[f]
                try:
                    f.result()
                except Interrupted:
                    continue
                except Exception as e:  # generation failed: a bug, report and keep going
                    c["error"] = f"{type(e).__name__}: {e}"
                    print(f"{c['id']}: {c['error']}", file=sys.stderr, flush=True)
                    continue
                done_count += 1
                (progress if run is None else progress_forced if args.forced_plan
                 else progress_friction if args.friction_plan
                 else progress_observed)(done_count, len(cases), c)
    except KeyboardInterrupt:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        STOP.set()
        with CHILDREN_LOCK:
            kids = list(CHILDREN)
        for p in kids:
            kill_group(p, signal.SIGTERM)
        deadline = time.monotonic() + 2.0
        for p in kids:
            try:
                p.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                kill_group(p, signal.SIGKILL)
        pool.shutdown(wait=False, cancel_futures=True)
        try:
            write(args, meta, cases, interrupted=True)
            print(f"interrupted; partial results in {args.out}", file=sys.stderr, flush=True)
        finally:
            os._exit(128 + int(got["signal"]))
    pool.shutdown()
    md, notes, body = write(args, meta, cases)
    print(notes + "\n")
    print(body)
    print(f"wrote {os.path.join(args.out, 'results.json')} and "
          f"{os.path.join(args.out, 'summary.md')}")
    errors = [c for c in cases if "error" in c]
    return 1 if errors else 0

