"""`csympnet fit` as a peer: the child process (killed on Ctrl-C) and its report.json."""
import json
import math
import os
import signal
import subprocess
import tempfile
import threading
import time

from ..common import check_stop

# ----------------------------------------------------------------------------------------------
# csympnet

CHILDREN = set()
CHILDREN_LOCK = threading.Lock()


def kill_group(p, sig):
    try:
        os.killpg(p.pid, sig)
    except (ProcessLookupError, PermissionError):
        pass


def run_child(cmd, timeout):
    check_stop()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)
    with CHILDREN_LOCK:
        CHILDREN.add(p)
    timed_out = False
    try:
        try:
            out, err = p.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            timed_out = True
            kill_group(p, signal.SIGKILL)
            out, err = p.communicate()
    finally:
        with CHILDREN_LOCK:
            CHILDREN.discard(p)
    check_stop()
    return p.returncode, out, err, timed_out


def run_child_cpu(cmd, timeout):
    """run_child, and the child's own CPU seconds (user + system, from wait4: exact whatever
    else runs beside it). Output through temporary files; the wait polls every 20 ms."""
    check_stop()
    with tempfile.TemporaryFile("w+") as fo, tempfile.TemporaryFile("w+") as fe:
        p = subprocess.Popen(cmd, stdout=fo, stderr=fe, text=True, start_new_session=True)
        with CHILDREN_LOCK:
            CHILDREN.add(p)
        timed_out = False
        deadline = time.monotonic() + timeout
        try:
            while True:
                pid, status, usage = os.wait4(p.pid, os.WNOHANG)
                if pid == p.pid:
                    p.returncode = os.waitstatus_to_exitcode(status)
                    break
                if time.monotonic() > deadline and not timed_out:
                    timed_out = True
                    kill_group(p, signal.SIGKILL)
                time.sleep(0.02)
        finally:
            with CHILDREN_LOCK:
                CHILDREN.discard(p)
        fo.seek(0)
        fe.seek(0)
        out, err = fo.read(), fe.read()
    check_stop()
    return p.returncode, out, err, timed_out, usage.ru_utime + usage.ru_stime


def num(v):
    """a finite JSON number as float, else None"""
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return None
    return float(v) if math.isfinite(float(v)) else None


def parse_checks(checks):
    """report.json's "checks" (one object per assumption) as a list of dicts, or None"""
    if not isinstance(checks, list):
        return None
    out = []
    for ch in checks:
        if not isinstance(ch, dict):
            continue
        rec = {"name": str(ch.get("name", "?")),
               "applicable": ch.get("applicable") if isinstance(ch.get("applicable"), bool)
               else None,
               "passed": ch.get("passed") if isinstance(ch.get("passed"), bool) else None}
        for k in ("statistic", "p_value", "alpha", "effect", "effect_threshold",
                  "detectable_effect"):
            rec[k] = num(ch.get(k))
        for k in ("assumption", "sentence"):
            rec[k] = ch.get(k) if isinstance(ch.get(k), str) else None
        rec["details"] = ch.get("details")
        out.append(rec)
    return out


def core_type(rep):
    """report.json "choices"."core"."type" (a core given as a string such as "la:5:20":
    the part before the first ':'), or None"""
    core = (rep.get("choices") or {}).get("core") if isinstance(rep.get("choices"), dict) \
        else None
    if isinstance(core, dict):
        t = core.get("type")
        return t if isinstance(t, str) else None
    if isinstance(core, str) and core:
        return core.split(":", 1)[0]
    return None


def stage_cpu_seconds(path):
    """timings.json's CPU seconds per stage name ("by_stage"), or None"""
    try:
        with open(path) as f:
            by = json.load(f).get("by_stage")
    except (OSError, ValueError):
        return None
    if not isinstance(by, dict):
        return None
    return {k: v.get("cpu_seconds") for k, v in by.items() if isinstance(v, dict)}


def run_csympnet(exe, data, outdir, extra, timeout, cpu=False):
    """`csympnet fit` on data; cpu: also the child's CPU seconds (cpu_seconds)."""
    cmd = [exe, "fit", data, "--out", outdir, "-q", "--no-figures", *extra]
    t0 = time.monotonic()
    if cpu:
        rc, out, err, timed_out, cpu_s = run_child_cpu(cmd, timeout)
    else:
        rc, out, err, timed_out = run_child(cmd, timeout)
    res = {"seconds": time.monotonic() - t0, "returncode": rc, "command": cmd,
           "stdout_tail": out.strip().splitlines()[-1] if out.strip() else ""}
    if cpu:
        res["cpu_seconds"] = cpu_s
    stages = stage_cpu_seconds(os.path.join(outdir, "timings.json"))
    if stages:
        res["stage_cpu_seconds"] = stages
    last_err = err.strip().splitlines()[-1] if err.strip() else ""
    if timed_out:
        res.update(status="failed", reason=f"timeout after {timeout} s")
        return res
    rep_path = os.path.join(outdir, "report.json")
    rep = None
    if rc in (0, 4, 5) and os.path.exists(rep_path):
        try:
            with open(rep_path) as f:
                rep = json.load(f)
        except (OSError, ValueError) as e:
            res.update(status="failed", reason=f"unreadable report.json: {e}")
            return res
    if rep is not None:
        res["verdict"] = rep.get("verdict")
        res["checks"] = parse_checks(rep.get("checks"))
        res["core_type"] = core_type(rep)
        if isinstance(rep.get("hamiltonian"), dict):
            res["hamiltonian"] = rep["hamiltonian"]
        terms = (rep.get("dissipation") or {}).get("terms") if isinstance(
            rep.get("dissipation"), dict) else None
        res["dissipation_kinds"] = sorted({t.get("kind") for t in terms or []
                                           if isinstance(t, dict) and t.get("kind") != "viscous"})
    if rc == 5 and rep is not None:  # model rejected: a verdict, counted apart
        failed = [ch.get("sentence") or ch["name"] for ch in res["checks"] or []
                  if ch["passed"] is False]
        res.update(status="rejected", identified=False,
                   reason="; ".join(failed) or rep.get("not_identified_reason", last_err),
                   gamma_hat=num(rep.get("gamma_hat")))
        return res
    if rc == 4:
        res.update(status="not_identified", identified=False,
                   reason=(rep or {}).get("not_identified_reason", last_err),
                   gamma_hat=num((rep or {}).get("gamma_hat")))
        return res
    if rc != 0 or rep is None:
        res.update(status="failed", reason=last_err or f"exit {rc}, no report.json")
        return res
    g = num(rep.get("gamma_hat"))
    identified = rep.get("identified", g is not None)
    res.update(gamma_hat=g, ci_low=num(rep.get("gamma_ci_low")),
               ci_high=num(rep.get("gamma_ci_high")), identified=bool(identified))
    if not identified:
        res.update(status="not_identified", reason=rep.get("not_identified_reason", ""))
    elif g is None:
        res.update(status="failed", reason="exit 0 but gamma_hat is not a number")
    else:
        res["status"] = "ok"
    return res


def run_csympnet_forced(exe, train, tests, outdir, extra, timeout, warmup):
    """`csympnet fit` on a forced record (t,q..,u.. columns), then `csympnet evaluate` of the
    fitted model on each test record (name -> path): the free-run RMS per output from the
    evaluation's report.json "simulation" "rmse". A fit that refuses the input columns (exit
    not 0/4/5, no report.json, its last error line naming the header or a column) is
    "unsupported" with that line as the reason. cpu_seconds: the fit's and the evaluations'."""
    res = run_csympnet(exe, train, outdir, extra, timeout, cpu=True)
    if res["status"] == "failed" and res.get("returncode") not in (0, 4, 5) \
            and not os.path.exists(os.path.join(outdir, "report.json")) \
            and any(w in res.get("reason", "") for w in ("header", "column")):
        res["status"] = "unsupported"
    model = os.path.join(outdir, "model.json")
    res["tests"] = {}
    if res["status"] in ("unsupported", "failed") or not os.path.exists(model):
        return res
    for name, path in tests.items():
        edir = os.path.join(outdir, f"evaluate-{name}")
        cmd = [exe, "evaluate", "--model", model, "--data", path, "--warmup", str(warmup),
               "--out", edir, "--force"]
        rc, out, err, timed_out, cpu_s = run_child_cpu(cmd, timeout)
        res["cpu_seconds"] = res.get("cpu_seconds", 0.0) + cpu_s
        r = {"command": cmd, "returncode": rc}
        rep = None
        try:
            with open(os.path.join(edir, "report.json")) as f:
                rep = json.load(f)
        except (OSError, ValueError):
            pass
        sim = (rep or {}).get("simulation") if isinstance(rep, dict) else None
        rmse = sim.get("rmse") if isinstance(sim, dict) else None
        if timed_out or rc != 0 or not isinstance(rmse, list):
            r.update(rms=None, diverged=None, status="failed",
                     reason=f"timeout after {timeout} s" if timed_out else
                     (err.strip().splitlines()[-1] if err.strip() else
                      f"exit {rc}, no simulation.rmse in report.json"))
        else:
            vals = [num(v) for v in rmse]
            r.update(status="ok", rms=None if None in vals else vals, diverged=None in vals)
        res["tests"][name] = r
    return res
