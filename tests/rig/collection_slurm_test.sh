#!/usr/bin/env bash
# A collection on a real one-node Slurm cluster (scripts/slurm-local.sh): three simulated
# sessions and the NeuralRTI icon's .lp run as Slurm jobs with the collection's own profile
# (Snakemake's cluster executor: sbatch, status.py asking sacct, scancel), every step one Slurm
# job asking for its rule's threads and memory; the fit of the .lp is cancelled with scancel
# while it runs, the rerun runs only what that left missing, the node drained during the rerun
# holds the jobs after it until resumed; a third run gives the fit too little memory and sees it
# killed and retried with twice the memory until it fits; sacct's records hold every job's
# state and request; the outputs equal a local run's byte for byte (docs/collection.md,
# "On Slurm").
#   collection_slurm_test.sh RIG SOURCE_DIR [SHARED_DIR]
# Exits 77 (CTest: skipped), saying why, when snakemake is missing or the cluster cannot be
# brought up here (not root, no slurm-wlm/munge, a daemon that does not start).
set -euo pipefail

if [ "${1:-}" = "--on-cluster" ]; then
  on_cluster=1; shift
else
  on_cluster=0
fi
rig=$1 src=$2 shared=${RIG_SHARED_DIR:-${3:-}}

if [ "$on_cluster" -eq 0 ]; then
  command -v snakemake >/dev/null 2>&1 || { echo "SKIPPED: snakemake is not installed"; exit 77; }
  t_start=$(date +%s.%N)
  work=$(mktemp -d "${TMPDIR:-/tmp}/rig-collection-slurm.XXXXXXXX")
  trap 'rm -rf -- "$work"' EXIT

  # One small simulated session (64x48, 21 poses, 5 exposures), captured once.
  sed -E -e 's/^width = [0-9]+/width = 64/' -e 's/^height = [0-9]+/height = 48/' \
      -e 's/^h_step_deg = [0-9.]+/h_step_deg = 15/' -e 's/^v_step_deg = [0-9.]+/v_step_deg = 15/' \
      -e 's/^count = [0-9]+/count = 5/' -- "$src/config/sim.toml" >"$work/sim.toml"
  "$rig" capture --config "$work/sim.toml" --out "$work/S" --dry-run --no-progress --no-process \
      >"$work/capture.log" 2>&1 || { cat "$work/capture.log"; exit 1; }
  rm -f -- "$work/S/.lock"

  icon="$shared/data/rti/neuralrti-example"
  # The local run and the Slurm run use the same paths ($work/run), one after the other, so that
  # outputs which name a path compare equal too.
  make_run() {
    rm -rf -- "$work/run"
    mkdir -p -- "$work/run/root/deeper"
    cp -a -- "$work/S" "$work/run/root/S1"
    cp -a -- "$work/S" "$work/run/root/S2"
    cp -a -- "$work/S" "$work/run/root/deeper/S3"
    if [ -n "$shared" ] && [ -f "$icon/dirs.lp" ]; then ln -s -- "$icon" "$work/run/root/icon"; fi
    "$rig" collection init "$work/run/coll" --root "$work/run/root" --formats relight \
        --session-evaluate-arg=--quick --no-evaluate-lp \
        --lp-fit-arg=--downsample --lp-fit-arg=2 >/dev/null
  }
  [ -f "$icon/dirs.lp" ] || echo "note: $icon is not here (RIG_SHARED_DIR): sessions only, no .lp entry, no scancel fault"

  # Requests scale with the image: a session whose frames are 6000x4000 JPEGs (24 MP; only the
  # header of one is written, which is all the workflow reads to plan) asks for 1.5x the peak
  # measured per megapixel (share/rig/Snakefile, _PEAKS) and 4x the time.
  mkdir -p -- "$work/big/root/B/frames/h000_v00"
  cp -- "$work/S/session.toml" "$work/S/journal.jsonl" "$work/big/root/B/"
  printf '\xff\xd8\xff\xc0\x00\x11\x08\x0f\xa0\x17\x70\x03\x01\x22\x00\x02\x11\x01\x03\x11\x01\xff\xd9' \
      >"$work/big/root/B/frames/h000_v00/0_0.02000.jpg"
  "$rig" collection init "$work/big/coll" --root "$work/big/root" --session-evaluate-arg=--quick >/dev/null
  (cd "$work/big/coll" && snakemake -n -j1 >"$work/big.log" 2>&1) || { cat "$work/big.log"; exit 1; }
  python3 - "$work/big.log" <<'EOF_BIG'
import re, sys
log = open(sys.argv[1]).read()
got = {m[1]: (int(m[2]), int(m[3])) for m in re.finditer(
    r"rule (\w+):(?:\n {4}.*)*?\n {4}resources: [^\n]*?mem_mb=(\d+)[^\n]*?runtime=(\d+)", log)}
# 1.5 x (MB0 + MB/MP x 24) up to 100 MB; 4 x (s0 + s/MP x 24) in minutes.
want = {"merge": (3100, 37), "fit_session": (33200, 20), "evaluate_session": (112100, 297),
        "export": (40700, 47)}
bad = {k: (got.get(k), v) for k, v in want.items() if got.get(k) != v}
print(("FAIL" if bad else "ok  ") + f" a 24 MP session's requests (mem_mb, runtime min): {got}" + (f" wanted {bad}" if bad else ""))
sys.exit(1 if bad else 0)
EOF_BIG

  make_run
  t0=$(date +%s.%N)
  (cd "$work/run/coll" && snakemake --profile profiles/local >"$work/local.log" 2>&1) ||
      { cat "$work/local.log"; echo "FAIL: the local run"; exit 1; }
  t1=$(date +%s.%N)
  echo "local run: wall $(printf '%.1f' "$(echo "$t1 - $t0" | bc)") s"
  echo "$t1 - $t0" | bc >"$work/local.wall"
  mv -- "$work/run" "$work/local"

  make_run
  rc=0
  bash "$src/scripts/slurm-local.sh" run -- bash "$0" --on-cluster "$rig" "$src" "$work" || rc=$?
  if [ "$rc" -eq 77 ] && [ ! -e "$work/cluster-was-up" ]; then
    echo "SKIPPED: the one-node Slurm cluster could not be brought up here (reason above)"
    exit 77
  fi
  echo "test wall time: $(printf '%.1f' "$(echo "$(date +%s.%N) - $t_start" | bc)") s"
  exit "$rc"
fi

# ---- on the cluster (SLURM_CONF and RIG_SLURM_DIR set by slurm-local.sh run) ----
work=$3
: >"$work/cluster-was-up"
coll="$work/run/coll"
cd -- "$coll"
has_lp=0
[ -e "$work/run/root/icon" ] && has_lp=1

# Snakemake 7.21's cluster executor asks status.py about each running job (at most
# max-status-checks-per-second of them a second, the profile's 2), then sleeps 10 s before the
# next round, or 1 s when CI=true (its own switch, executors/__init__.py sleep()): the test
# takes the 1 s round so that a job's end is seen within a second or two; a cluster's users
# keep the 10 s. Everything else is the profile as a user runs it.
export CI=true
# Run 1, in the background; the .lp's fit is cancelled (scancel) while it runs. Without the
# profile's retries (which would submit the cancelled job again within the run): the rerun, a
# second snakemake, is what picks it up.
t0=$(date +%s.%N)
snakemake --profile profiles/slurm --retries 0 >"$work/slurm1.log" 2>&1 &
snake=$!
cancelled=""
if [ "$has_lp" -eq 1 ]; then
  for _ in $(seq 1200); do  # 120 s
    cancelled=$(squeue -h -t R -o '%i %j' | awk '$2 ~ /^snakejob_fit_lp_/ {print $1; exit}')
    [ -n "$cancelled" ] && break
    kill -0 "$snake" 2>/dev/null || break
    sleep 0.1
  done
  [ -n "$cancelled" ] || { cat "$work/slurm1.log"; echo "FAIL: the fit of the .lp never ran as a Slurm job"; exit 1; }
  # Mid-fit: its rig fit has started (the job's shell line has opened its log) and has not
  # written its report.
  for _ in $(seq 300); do
    [ -e "$coll/logs/fit/icon__dirs.log" ] && break
    sleep 0.05
  done
  sleep 0.5
  if [ -e "$coll/results/icon__dirs/fit.md" ]; then
    echo "FAIL: the fit finished before it could be cancelled (make the .lp fit longer)"; exit 1
  fi
  scancel "$cancelled"
  echo "scancel $cancelled (fit_lp, running for $(squeue -h -j "$cancelled" -o %M 2>/dev/null || echo '?'))"
fi
rc1=0
wait "$snake" || rc1=$?
t1=$(date +%s.%N)
# What the cancelled fit had written was removed by Snakemake (a failed job's outputs are).
left_behind=0
[ -e "$coll/results/icon__dirs/model" ] || [ -e "$coll/results/icon__dirs/fit.md" ] && left_behind=1

# What is left: planned by a dry run, before the rerun.
snakemake -n --profile profiles/slurm >"$work/plan.log" 2>&1 || { cat "$work/plan.log"; exit 1; }
# Run 2: to the end.
t2=$(date +%s.%N)
# Run 2, to the end; the node is drained while the fit runs again (it finishes: a drain takes
# no new jobs and lets running ones end), the jobs after it wait in the queue, and the node is
# resumed: they run then, once each.
snakemake --profile profiles/slurm >"$work/slurm2.log" 2>&1 &
snake=$!
drained=""
if [ "$has_lp" -eq 1 ]; then
  host=$(hostname -s)
  for _ in $(seq 1200); do
    [ -n "$(squeue -h -t R -o '%j' | grep '^snakejob_fit_lp_' || true)" ] && break
    kill -0 "$snake" 2>/dev/null || break
    sleep 0.1
  done
  scontrol update NodeName="$host" State=DRAIN Reason=rig-collection-slurm-test
  # Held: a job of the run pending while the node is drained (or draining).
  for _ in $(seq 600); do
    state=$(sinfo -h -N -n "$host" -o %t)
    pending=$(squeue -h -t PD -o '%j' | grep -c '^snakejob_' || true)
    if [ "$pending" -gt 0 ] && [ "$state" = "drain" ]; then drained="$pending job(s) pending on the drained node"; break; fi
    kill -0 "$snake" 2>/dev/null || break
    sleep 0.1
  done
  sleep 2
  scontrol update NodeName="$host" State=RESUME
fi
rc2=0
wait "$snake" || rc2=$?
t3=$(date +%s.%N)
echo "$drained" >"$work/drained"
echo "$t1 - $t0" | bc >"$work/slurm1.wall"
echo "$t3 - $t2" | bc >"$work/slurm2.wall"

# Run 3: the .lp's fit run again (--forcerun) asking for far less memory than it uses (60 MB, as
# written: from_image_size: false); the cluster kills it over its --mem (OverMemoryKill), the
# profile's retries submit it again asking for twice as much each time, and it ends well. The
# collection's config.yaml is put back byte for byte afterwards.
rc3=0
if [ "$has_lp" -eq 1 ]; then
  cp -- config.yaml "$work/config.yaml.orig"
  grep -q '^  fit_lp: {threads: 2, mem_mb: 1000}$' config.yaml ||
      { cat config.yaml; echo "FAIL: config.yaml has no fit_lp line to lower"; exit 1; }
  sed -i 's/^  fit_lp: {threads: 2, mem_mb: 1000}$/  fit_lp: {threads: 2, mem_mb: 60, from_image_size: false}/' config.yaml
  snakemake --profile profiles/slurm --retries 3 --forcerun fit_lp >"$work/slurm3.log" 2>&1 || rc3=$?
  cp -- "$work/config.yaml.orig" config.yaml
  grep -c 'exceeded memory limit' "$RIG_SLURM_DIR/log/slurmd.log" >"$work/oom.count" || echo 0 >"$work/oom.count"
fi
cp -- "$RIG_SLURM_DIR/jobcomp.txt" "$work/jobcomp.txt" 2>/dev/null || : >"$work/jobcomp.txt"
# Slurm's accounting, as a cluster's users read it (slurmdbd and MariaDB, when installed).
if sacct -X -P -n -S "$(date -d '-1 day' +%Y-%m-%dT%H:%M:%S)" \
     --format=JobID,JobName,State,ReqTRES,Submit,Start,End >"$work/sacct.txt" 2>"$work/sacct.err"; then
  echo "sacct: $(wc -l <"$work/sacct.txt") jobs"
else
  echo "note: sacct answers nothing here ($(head -c 200 "$work/sacct.err")); the job records are jobcomp.txt"
  : >"$work/sacct.txt"
fi

python3 - "$work" "$rc1" "$rc2" "$cancelled" "$has_lp" "$left_behind" "$rc3" <<'EOF_PY'
"""Checks the two Slurm runs against each other, against Slurm's job records and against the
local run; prints the figures docs/collection.md quotes."""
import csv, os, re, sys
from datetime import datetime
from pathlib import Path

work, rc1, rc2, cancelled, has_lp = Path(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4], sys.argv[5] == "1"
left_behind = sys.argv[6] == "1"
rc3 = int(sys.argv[7])
fails = []
def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        fails.append(what)

def jobs(log):
    """Snakemake's job blocks: jobid -> {rule, wildcards, threads, mem_mb}; and the finished ids,
    and Snakemake job id -> Slurm job id."""
    blocks, cur = {}, None
    for line in log.splitlines():
        m = re.match(r"^(local)?rule (\w+):\s*$", line)
        if m:
            cur = {"rule": m[2], "wildcards": "", "threads": 1, "mem_mb": None, "local": bool(m[1])}
            continue
        if cur is None:
            continue
        if not line.startswith(" "):  # the block ends ("Error in rule X:" blocks repeat "jobid:")
            cur = None
            continue
        if m := re.match(r"^\s+jobid: (\d+)", line):
            cur["id"] = int(m[1]); blocks[int(m[1])] = cur
        elif m := re.match(r"^\s+wildcards: (.*)$", line):
            cur["wildcards"] = m[1]
        elif m := re.match(r"^\s+threads: (\d+)", line):
            cur["threads"] = int(m[1])
        elif m := re.match(r"^\s+resources: (.*)$", line):
            if r := re.search(r"\bmem_mb=(\d+)", m[1]):
                cur["mem_mb"] = int(r[1])
    done = [int(x) for x in re.findall(r"Finished job (\d+)\.", log)]
    slurm = {int(a): b for a, b in re.findall(r"Submitted job (\d+) with external jobid '(\d+)'", log)}
    return blocks, done, slurm

def key(b):
    return f"{b['rule']}[{b['wildcards']}]"

logs = [(work / f).read_text() for f in ("slurm1.log", "slurm2.log")]
plan_blocks, _, _ = jobs((work / "plan.log").read_text())
planned_left = {key(b) for b in plan_blocks.values()}
runs = [jobs(l) for l in logs]
local_blocks, local_done, _ = jobs((work / "local.log").read_text())
all_keys = {key(b) for b in local_blocks.values()}

check(rc2 == 0, f"the second Slurm run ends well (exit {rc2})")
finished = {}
for blocks, done, _ in runs:
    for i in done:
        finished[key(blocks[i])] = finished.get(key(blocks[i]), 0) + 1
check(set(finished) == all_keys, f"the Slurm runs did the local run's {len(all_keys)} jobs")
twice = [k for k, n in finished.items() if n != 1]
check(not twice, "every job finished exactly once over the two runs" + (f" (not: {twice})" if twice else ""))

# Every non-local job was a Slurm job; Slurm's records hold each one with the rule's threads and
# memory: sacct's (slurmdbd) where the cluster keeps accounting, else the job-completion log's.
comp = {}
sacct = (work / "sacct.txt").read_text().splitlines()
for line in sacct:
    f = line.split("|")
    if len(f) == 7:
        comp[f[0]] = {"JobState": f[2].split()[0] if f[2] else "", "Tres": f[3], "SubmitTime": f[4],
                      "StartTime": f[5], "EndTime": f[6]}
source = "sacct"
if not comp:
    source = "jobcomp.txt"
    for line in (work / "jobcomp.txt").read_text().splitlines():
        rec = dict(f.split("=", 1) for f in line.split() if "=" in f)
        if "JobId" in rec:
            comp[rec["JobId"]] = rec
print(f"     job records from {source}: {len(comp)} jobs")
n_slurm, waits, overheads = 0, [], []
for blocks, done, slurm in runs:
    for i, b in blocks.items():
        if b["local"]:
            continue
        if i not in slurm:
            check(False, f"{key(b)} was submitted to Slurm"); continue
        n_slurm += 1
        rec = comp.get(slurm[i])
        if rec is None:
            check(False, f"Slurm job {slurm[i]} ({key(b)}) is in Slurm's job records ({source})"); continue
        tres = dict(t.split("=", 1) for t in rec.get("Tres", "").split(",") if "=" in t)
        want_state = "CANCELLED" if slurm[i] == cancelled else "COMPLETED"
        ok = (rec.get("JobState") == want_state and tres.get("cpu") == str(b["threads"])
              and tres.get("mem") == f"{b['mem_mb']}M")
        check(ok, f"Slurm job {slurm[i]}: {key(b)} {rec.get('JobState')} cpu={tres.get('cpu')} "
                  f"mem={tres.get('mem')} (rule: {b['threads']} threads, mem_mb={b['mem_mb']})")
        if want_state == "COMPLETED":
            t = lambda f: datetime.fromisoformat(rec[f])
            waits.append((t("StartTime") - t("SubmitTime")).total_seconds())
            # The job's time in Slurm (submitted to ended) less its command's own time (Snakemake's
            # benchmark of the shell line): what running it as a Slurm job cost.
            w = dict(x.split("=", 1) for x in b["wildcards"].split(", ") if "=" in x)
            step = {"fit_session": "fit", "fit_lp": "fit", "evaluate_session": "evaluate",
                    "evaluate_lp": "evaluate"}.get(b["rule"], b["rule"])
            tsv = work / "run/coll/benchmarks" / step / (w.get("name", "") + (f".{w['format']}" if "format" in w else "") + ".tsv")
            if tsv.is_file():
                row = next(csv.DictReader(tsv.open(), delimiter="\t"))
                overheads.append((t("EndTime") - t("SubmitTime")).total_seconds() - float(row["s"]))

# The cancelled job: Snakemake saw it cancelled, removed what it had written, and the rerun
# ran exactly what was left: that fit and what follows from it.
if has_lp:
    check(bool(cancelled), "a fit_lp Slurm job was found running and cancelled")
    check(rc1 != 0 and f"Error executing rule fit_lp on cluster (jobid: " in logs[0]
          and f"external: {cancelled}," in logs[0],
          f"the first run saw the job cancelled and failed it (exit {rc1})")
    b1, d1, _ = runs[0]
    left = all_keys - {key(b1[i]) for i in d1}
    check(planned_left == left, f"what the rerun plans is what the first run left undone: {sorted(planned_left)}")
    check("fit_lp[name=icon__dirs]" in planned_left, "the cancelled fit is among it")
    check(not left_behind, "nothing the cancelled fit wrote was left (its model folder and report removed)")
    second = {key(b) for b in runs[1][0].values()}
    check(second == planned_left, "the rerun ran exactly that")
    check(not any("S1" in k or "S2" in k or "S3" in k for k in second), "no session job ran again")
    drained = (work / "drained").read_text().strip()
    check(bool(drained), "the node drained mid-run held the next jobs" + (f" ({drained})" if drained else ""))

# The job over its memory: each attempt a Slurm job asking for twice the last one's memory, those
# killed over it FAILED in Slurm's records (slurmd logged each kill), the last COMPLETED, and
# the run did the fit and what follows from it, no session job.
if has_lp:
    log3 = (work / "slurm3.log").read_text()
    b3, d3, _ = jobs(log3)
    check(rc3 == 0, f"the run with the fit's memory too small ends well (exit {rc3})")
    fit_ids = [i for i, b in b3.items() if b["rule"] == "fit_lp"]
    subs = {}
    for a, b in re.findall(r"Submitted job (\d+) with external jobid '(\d+)'", log3):
        subs.setdefault(int(a), []).append(b)
    tries = subs.get(fit_ids[0], []) if fit_ids else []
    recs = [comp.get(j, {}) for j in tries]
    mems = [dict(t.split("=", 1) for t in r.get("Tres", "").split(",") if "=" in t).get("mem") for r in recs]
    states = [r.get("JobState") for r in recs]
    want_mems = [f"{60 * 2 ** k}M" for k in range(len(tries))]
    oom = int((work / "oom.count").read_text().split()[0] or 0)
    check(len(tries) >= 2 and states[-1] == "COMPLETED"
          and all(x in ("FAILED", "OUT_OF_MEMORY") for x in states[:-1])
          and mems == want_mems and oom >= len(tries) - 1,
          f"the fit over its memory: Slurm jobs {tries}, {states}, mem {mems} (doubling from 60M), "
          f"{oom} kill(s) over the memory limit in slurmd's log")
    ran3 = {key(b) for i, b in b3.items() if i in d3}
    check("fit_lp[name=icon__dirs]" in ran3 and not any("S1" in k or "S2" in k or "S3" in k for k in ran3),
          f"it reran the fit and what follows from it, no session job: {sorted(ran3)}")

# Outputs: the local run's and the Slurm run's trees (the sessions and the collection folder),
# byte for byte. Not compared: what records how or how long a job ran (logs/, benchmarks/,
# .snakemake/), and, listed by name, the files that hold a measured time (fit and evaluation
# reports, the collection's table and chart), the session's log.txt (timestamped lines) and
# its .lock (the id of the last rig process).
SKIP_DIRS = {".snakemake", "logs", "benchmarks"}
TIMED = re.compile(r"(^|/)(\.lock|log\.txt|model/report\.md|fit\.md|report/collection\.(md|csv|png)|report/index\.html|"
                   r"evaluate/.*|.*\.log|snakemake-run\.log)$")
def tree(root):
    """relative path -> ("file", bytes) or ("link", target); links are not followed."""
    out = {}
    for d, dirs, files in os.walk(root):
        for name in files + dirs:
            p = Path(d, name)
            rel = str(p.relative_to(root))
            if p.is_symlink():
                out[rel] = ("link", os.readlink(p))
            elif p.is_file():
                out[rel] = ("file", p.read_bytes())
        dirs[:] = [x for x in dirs if x not in SKIP_DIRS and not Path(d, x).is_symlink()]
    return out
local, slurm_t = tree(work / "local"), tree(work / "run")
check(set(local) == set(slurm_t), "the same files" + (
    f" (only local: {sorted(set(local) - set(slurm_t))[:5]}, only Slurm: {sorted(set(slurm_t) - set(local))[:5]})"
    if set(local) != set(slurm_t) else ""))
same, timed, differ = 0, [], []
for rel in sorted(set(local) & set(slurm_t)):
    if local[rel] == slurm_t[rel]:
        same += 1
    elif TIMED.search(rel):
        timed.append(rel)
    else:
        differ.append(rel)
check(not differ, f"{same} files byte for byte equal, {len(timed)} differing only where a time is recorded"
      + (f"; differing: {differ[:10]}" if differ else ""))
for rel in timed:
    print(f"     (differs, holds a time or a process id: {rel})")

wall_local = float((work / "local.wall").read_text())
wall_s = float((work / "slurm1.wall").read_text()) + float((work / "slurm2.wall").read_text())
n_jobs = len([b for b in local_blocks.values() if not b["local"]])
print(f"figures: {n_slurm} Slurm jobs ({n_jobs} in one run of the collection); wall: local "
      f"{wall_local:.1f} s, Slurm {wall_s:.1f} s over the two runs; queue wait (submit to start) "
      f"mean {sum(waits) / max(len(waits), 1):.1f} s, max {max(waits, default=0):.0f} s; Slurm's time "
      f"per job less the command's own: mean {sum(overheads) / max(len(overheads), 1):.1f} s over "
      f"{len(overheads)} jobs (Slurm's times have 1 s resolution)")
sys.exit(1 if fails else 0)
EOF_PY
