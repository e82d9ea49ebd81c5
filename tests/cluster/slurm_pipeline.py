"""The quick protocol's table1 and table3 on a running SLURM cluster, checked against a local run.

Started by tests/cluster/run_slurm_test.sh once SLURM is up (it is not a pytest module, so the main
suite never collects it). Three checks, each failing with what differed:

1. ``snakemake table1 table3 --profile profiles/slurm-noacct`` finishes (with a time limit: a status
   check that never sees the jobs end would otherwise wait forever) while a local ``-c 1`` run of the
   same tables runs beside it;
2. every file under ``<results>/tables`` and ``<results>/runs`` is byte-identical between the two
   (tests/reproducible.py; the jobs' times are apart, under ``<results>/timings``);
3. every ``run_job`` job reached SLURM (``scontrol show job``, which keeps finished jobs for MinJobAge
   seconds) with its rule's threads, memory and runtime, as nldr.experiments declares them, and
   completed there; no other job was submitted (the gathering rules run on the submitting host).
"""

from __future__ import annotations

import argparse
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "tests"))
from protocol import QUICK, SNAKEMAKE, quick_config  # noqa: E402
from reproducible import compare_runs  # noqa: E402

from nldr.experiments import EXPERIMENTS  # noqa: E402

TARGETS = ["table1", "table3"]
PROFILE = REPO / "profiles" / "slurm-noacct"
TIME_LIMIT = 900  # s for the SLURM run; a hang shows as this timeout, not as a stuck CI job


def start(workdir: Path, args: list[str], log: Path) -> subprocess.Popen:
    workdir.mkdir(parents=True, exist_ok=True)
    cmd = [*SNAKEMAKE, "-d", str(workdir), *args, "--configfile", str(QUICK)]
    out = log.open("w")
    return subprocess.Popen(cmd, cwd=REPO, stdout=out, stderr=subprocess.STDOUT, start_new_session=True)


def finish(proc: subprocess.Popen, log: Path, what: str, deadline: float) -> None:
    try:
        rc = proc.wait(timeout=max(1.0, deadline - time.monotonic()))
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)  # its own session: snakemake and its children only
        proc.wait()
        sys.exit(f"{what} did not finish within {TIME_LIMIT} s; last lines of {log}:\n{tail(log)}")
    if rc != 0:
        sys.exit(f"{what} failed (exit {rc}); last lines of {log}:\n{tail(log)}")


def tail(path: Path, n: int = 40) -> str:
    return "\n".join(path.read_text(errors="replace").splitlines()[-n:])


def compare(local: Path, cluster: Path, results: str) -> int:
    """Every file under tables/ and runs/ of both runs, byte for byte (tests/reproducible.py): how
    many were compared; exits naming each difference."""
    count, problems = compare_runs(local, cluster, results, ("tables", "runs"))
    if problems:
        sys.exit("outputs differ between the local and the SLURM run:\n  " + "\n  ".join(problems))
    return count


def expected_requests() -> dict[str, tuple[int, int, int]]:
    """SLURM comment of each run_job job -> (threads, mem_mb, runtime in minutes) its rule declares."""
    config = quick_config()
    out = {}
    for name in TARGETS:
        experiment = EXPERIMENTS[name]
        for job in experiment.check(config):
            res = experiment.resources(config, job)
            key = f"rule_run_job_wildcards_{name}_{job.id}"  # the plugin's --comment
            out[key] = (experiment.threads(config, job), int(res["mem_mb"]), int(res["runtime"]))
    return out


def minutes(limit: str) -> int:
    """SLURM's TimeLimit ('[D-]HH:MM:SS' or 'MM:SS') in whole minutes."""
    days, _, clock = limit.rpartition("-")
    parts = [int(x) for x in clock.split(":")]
    while len(parts) < 3:
        parts.insert(0, 0)
    h, m, s = parts
    return (int(days or 0) * 24 + h) * 60 + m + (1 if s else 0)


def submitted_jobs() -> list[dict[str, str]]:
    text = subprocess.run(
        ["scontrol", "show", "job", "-o"], capture_output=True, text=True, check=True
    ).stdout
    return [dict(re.findall(r"(\S+?)=(\S*)", line)) for line in text.splitlines() if line.strip()]


def check_requests(run_uuid: str) -> int:
    """Each run_job job's request against its rule; returns the number of jobs checked."""
    want = expected_requests()
    jobs = [j for j in submitted_jobs() if j.get("JobName") == run_uuid]
    seen, problems = {}, []
    for job in jobs:
        comment = job.get("Comment", "")
        got = (int(job["CPUs/Task"]), int(job["MinMemoryNode"].rstrip("M")), minutes(job["TimeLimit"]))
        if comment in seen:
            problems.append(f"{comment} submitted twice (jobs {seen[comment][0]} and {job['JobId']})")
        seen[comment] = (job["JobId"], got)
        if comment not in want:
            problems.append(f"job {job['JobId']} ({comment}) is not a run_job job of {TARGETS}")
        elif got != want[comment]:
            problems.append(
                f"{comment}: SLURM got cpus/task, mem MB, minutes {got}, the rule declares {want[comment]}"
            )
        if job.get("JobState") != "COMPLETED":
            problems.append(f"{comment}: state {job.get('JobState')}")
    for comment in sorted(want.keys() - seen.keys()):
        problems.append(f"{comment} never reached SLURM")
    if problems:
        sys.exit("SLURM requests:\n  " + "\n  ".join(problems))
    for comment, (jobid, got) in sorted(seen.items(), key=lambda kv: int(kv[1][0])):
        print(f"  job {jobid:>4} {comment}: cpus/task {got[0]}, mem {got[1]} MB, {got[2]} min")
    return len(seen)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--workdir", type=Path, required=True, help="scratch folder for both runs")
    args = parser.parse_args()
    results = quick_config()["results"]
    local, cluster = args.workdir / "local", args.workdir / "slurm"
    t0 = time.monotonic()
    deadline = t0 + TIME_LIMIT
    tables = [f"{results}/tables/{name}.csv" for name in TARGETS]
    local_log, cluster_log = args.workdir / "local.log", args.workdir / "slurm.log"
    slurm = start(cluster, [*TARGETS, "--profile", str(PROFILE)], cluster_log)
    here = start(local, [*tables, "-c", "1"], local_log)
    finish(here, local_log, "the local run", deadline)
    t_local = time.monotonic() - t0
    finish(slurm, cluster_log, "the SLURM run", deadline)
    t_slurm = time.monotonic() - t0
    match = re.search(r"SLURM run ID: (\S+)", cluster_log.read_text())
    if not match:
        sys.exit(f"no 'SLURM run ID' in {cluster_log}: did the slurm executor run?")
    print(f"local run {t_local:.0f} s, SLURM run {t_slurm:.0f} s (side by side)")
    n_files = compare(local, cluster, results)
    print(f"{n_files} files under {results}/tables and {results}/runs: byte-identical")
    n_jobs = check_requests(match.group(1))
    print(f"{n_jobs} SLURM jobs, each with its rule's threads, memory and runtime: OK")


if __name__ == "__main__":
    main()
