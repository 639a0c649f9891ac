#!/bin/sh
# Smoke test of experiments/identification_benchmark.py: four small cases. Passes when the
# script exits 0 and DIR/results.json parses and holds 4 cases, each with a sindy and an oracle
# result and, when CSYMPNET names the binary (ctest does), a csympnet result that is a number
# or a verdict ("not identified", "model rejected"; tiny budgets), never a failure. Then two
# cases of the observed-records plan (--observed-plan): the oracle covers, the textbook fit
# and csympnet (with its CPU seconds) give an answer.
# Usage: [CSYMPNET=build/bin/csympnet] tests/experiments/identification_benchmark_smoke.sh
#        (PYTHON overrides /usr/bin/python3)
set -u
here=$(cd "$(dirname "$0")" && pwd)
repo=$(cd "$here/../.." && pwd)
py=${PYTHON:-/usr/bin/python3}
cli=${CSYMPNET:-}
tmp=$(mktemp -d "${TMPDIR:-/tmp}/idbench-smoke.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT INT TERM

if [ -n "$cli" ]; then
  "$py" "$repo/experiments/identification_benchmark.py" --quick --cases 4 --csympnet "$cli" \
    --fit-args="--epochs 200 --lm-iterations 10" --out "$tmp/out" >"$tmp/log" 2>&1
else
  "$py" "$repo/experiments/identification_benchmark.py" --quick --only-peers --cases 4 \
    --out "$tmp/out" >"$tmp/log" 2>&1
fi
rc=$?
if [ "$rc" -ne 0 ]; then
  cat "$tmp/log"
  echo "FAIL: identification_benchmark.py exited $rc"
  exit 1
fi
"$py" - "$tmp/out/results.json" "$cli" <<'PYEOF'
import json
import sys
with_cli = len(sys.argv) > 2 and sys.argv[2] != ""

with open(sys.argv[1]) as f:
    r = json.load(f)
cases = r["cases"]
assert len(cases) == 4, f"expected 4 cases, got {len(cases)}"
for c in cases:
    for m in ("sindy", "oracle"):
        assert m in c["methods"], f"{c['id']}: no {m} result"
    status = c["methods"]["csympnet"]["status"]
    if with_cli:
        assert status in ("ok", "not_identified", "rejected"), \
            f"{c['id']}: csympnet {c['methods']['csympnet']}"
    else:
        assert status == "skipped", c["id"]
    assert c["gamma_true"] > 0, c["id"]
print("identification benchmark smoke: 4 cases, oracle relative errors",
      ", ".join(f"{c['methods']['oracle'].get('rel_err', float('nan')):.1e}" for c in cases))
PYEOF
rc=$?
if [ "$rc" -ne 0 ]; then
  echo "FAIL: results.json check"
  exit 1
fi
[ -s "$tmp/out/summary.md" ] || { echo "FAIL: no summary.md"; exit 1; }

# The observed-records plan: two small records (two carts in pixels, an encoder), every method
# in one run.
if [ -n "$cli" ]; then
  "$py" "$repo/experiments/identification_benchmark.py" --observed-plan --quick --cases 2 \
    --observed-strata linear-px,encoder --csympnet "$cli" \
    --fit-args="--epochs 200 --lm-iterations 10" --out "$tmp/obs" >"$tmp/log" 2>&1
else
  "$py" "$repo/experiments/identification_benchmark.py" --observed-plan --quick --only-peers \
    --cases 2 --observed-strata linear-px,encoder --out "$tmp/obs" >"$tmp/log" 2>&1
fi
rc=$?
if [ "$rc" -ne 0 ]; then
  cat "$tmp/log"
  echo "FAIL: identification_benchmark.py --observed-plan exited $rc"
  exit 1
fi
"$py" - "$tmp/obs/results.json" "$cli" <<'PYEOF'
import json
import sys
with_cli = len(sys.argv) > 2 and sys.argv[2] != ""

with open(sys.argv[1]) as f:
    r = json.load(f)
cases = r["cases"]
assert [c["stratum"] for c in cases] == ["linear-px", "encoder"], cases
for c in cases:
    m = c["methods"]
    assert m["oracle"]["status"] == "ok" and m["oracle"]["covers"], (c["id"], m["oracle"])
    assert m["textbook"]["status"] == "ok", (c["id"], m["textbook"])
    status = m["csympnet"]["status"]
    if with_cli:
        assert status in ("ok", "not_identified", "rejected"), (c["id"], m["csympnet"])
        assert m["csympnet"]["cpu_seconds"] > 0, c["id"]
    else:
        assert status == "skipped", c["id"]
print("observed plan smoke: oracle relative errors",
      ", ".join(f"{c['methods']['oracle']['rel_err']:.1e}" for c in cases))
PYEOF
rc=$?
if [ "$rc" -ne 0 ]; then
  echo "FAIL: observed plan results.json check"
  exit 1
fi
echo "PASS"
