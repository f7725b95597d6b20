#!/usr/bin/env python3
"""A Slurm job's state for Snakemake's cluster executor (the slurm profile's cluster-status):
prints one of running, success, failed for the job id given.

Asks sacct (the cluster's accounting) first and the controller (scontrol) when sacct cannot
answer (a cluster without accounting, or a job sacct has not recorded yet). Every state Slurm
ends a job in but COMPLETED is a failure, whatever follows the state's name: sacct says
"CANCELLED by 1000" for a job cancelled by that user, which Snakemake 7.21's own Slurm
executor does not recognise (it waits for such a job forever). A job neither knows is taken as
failed, so Snakemake runs it again rather than waiting for it.
"""
import re
import subprocess
import sys

RUNNING = {"PENDING", "CONFIGURING", "RUNNING", "COMPLETING", "SUSPENDED", "REQUEUED",
           "REQUEUE_FED", "REQUEUE_HOLD", "RESIZING", "SIGNALING", "STAGE_OUT", "STOPPED",
           "RESV_DEL_HOLD", "SPECIAL_EXIT"}


def ask(cmd):
    try:
        return subprocess.run(cmd, check=True, capture_output=True, text=True, timeout=60).stdout
    except (OSError, subprocess.SubprocessError):
        return ""


def state(jobid):
    out = ask(["sacct", "-X", "-P", "-n", "-j", jobid, "--format=JobIdRaw,State"])
    for line in out.splitlines():
        f = line.split("|")
        if len(f) == 2 and f[0] == jobid and f[1].strip():
            return f[1].split()[0]
    m = re.search(r"\bJobState=(\S+)", ask(["scontrol", "show", "job", jobid]))
    return m[1] if m else None


def main():
    if len(sys.argv) != 2:
        print("usage: status.py JOBID", file=sys.stderr)
        return 2
    jobid = sys.argv[1].split(";")[0].strip()  # sbatch --parsable: "id" or "id;cluster"
    if not re.fullmatch(r"[0-9]+(_[0-9]+)?", jobid):
        print(f"status.py: '{sys.argv[1]}' is not a Slurm job id", file=sys.stderr)
        return 2
    s = state(jobid)
    if s is None:
        print(f"status.py: Slurm job {jobid} is known to neither sacct nor scontrol: taken as failed",
              file=sys.stderr)
        print("failed")
    elif s == "COMPLETED":
        print("success")
    elif s in RUNNING:
        print("running")
    else:
        print(f"status.py: Slurm job {jobid} ended {s}", file=sys.stderr)
        print("failed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
