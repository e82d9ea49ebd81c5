#!/usr/bin/env bash
# The pipeline on a real one-node SLURM cluster (run as root; `make cluster-test`, .ci/run):
#   - installs Debian's slurmctld, slurmd, slurm-client and munge when they are missing;
#   - writes munge's key and a one-node slurm.conf (from `slurmd -C`) into a temporary folder, with no
#     accounting (no slurmdbd), and starts munged, slurmctld and slurmd by hand (no systemd needed);
#   - runs tests/cluster/slurm_pipeline.py (the quick protocol's table1 and table3 through
#     profiles/slurm-noacct, compared byte for byte with a local run; each job's SLURM request checked);
#   - stops the daemons by their pids on every exit, failure included.
# If SLURM cannot be started the test fails and says why; it never skips.
# NLDR_SLURM_KEEP=1 keeps the temporary folder (configs, daemon logs, both runs) for a post-mortem.
# `run_slurm_test.sh -- CMD ARGS...` runs CMD on the started cluster instead of the test (e.g. to try
# the README's cluster commands), then stops the cluster the same way.
set -euo pipefail
REPO="$(cd "$(dirname "$0")/../.." && pwd)"
PYTHON="${NLDR_PYTHON:-$REPO/.venv/bin/python}"
fail() { echo "cluster test FAILED: $*" >&2; exit 1; }

[ "$(id -u)" -eq 0 ] || fail "needs root: it installs the SLURM packages and starts munged, slurmctld and slurmd"
[ -x "$PYTHON" ] || fail "no Python at $PYTHON (run 'make setup' first, or set NLDR_PYTHON)"

# one cluster test per machine at a time (the daemons listen on fixed ports, and use /etc/slurm/slurm.conf)
exec 9>/tmp/nldr-slurm-test.lock
flock -w 900 9 || fail "another cluster test still holds /tmp/nldr-slurm-test.lock after 15 min"

missing=""
for tool in munged mungekey slurmctld slurmd sbatch squeue scontrol sinfo; do
    command -v "$tool" >/dev/null 2>&1 || missing="$missing $tool"
done
if [ -n "$missing" ]; then
    echo "installing slurmctld slurmd slurm-client munge (missing:$missing)"
    export DEBIAN_FRONTEND=noninteractive
    if ! apt-get install -y -q slurmctld slurmd slurm-client munge >/tmp/nldr-slurm-apt.log 2>&1; then
        apt-get update -q >>/tmp/nldr-slurm-apt.log 2>&1 || true
        apt-get install -y -q slurmctld slurmd slurm-client munge >>/tmp/nldr-slurm-apt.log 2>&1 \
            || { tail -20 /tmp/nldr-slurm-apt.log >&2; fail "apt-get could not install the SLURM packages"; }
    fi
fi

WORK="$(mktemp -d /tmp/nldr-slurm.XXXXXX)"
chmod 755 "$WORK"  # munged insists that every user can reach its socket's folder
CONF="$WORK/slurm.conf"
SYSCONF=/etc/slurm/slurm.conf
PIDS=()
LINKED=0

cleanup() {
    local rc=$?
    set +e
    for ((i = ${#PIDS[@]} - 1; i >= 0; i--)); do  # slurmd, slurmctld, munged: the reverse of starting
        kill "${PIDS[i]}" 2>/dev/null
        for _ in $(seq 50); do kill -0 "${PIDS[i]}" 2>/dev/null || break; sleep 0.1; done
        kill -9 "${PIDS[i]}" 2>/dev/null
    done
    wait 2>/dev/null
    [ "$LINKED" -eq 1 ] && [ "$(readlink "$SYSCONF")" = "$CONF" ] && rm -f "$SYSCONF"
    if [ "$rc" -ne 0 ]; then
        for log in slurmctld.log slurmd.log munged.log; do
            [ -f "$WORK/$log" ] && { echo "--- last lines of $log" >&2; tail -15 "$WORK/$log" >&2; }
        done
    fi
    if [ "${NLDR_SLURM_KEEP:-0}" = 1 ]; then echo "kept $WORK"; else rm -rf "$WORK"; fi
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# munge: its own key, socket, log and pid file in $WORK (no /etc/munge, /run/munge needed)
mungekey --create --keyfile="$WORK/munge.key" || fail "mungekey could not create a key"
munged -F --force --socket="$WORK/munge.socket" --key-file="$WORK/munge.key" \
    --log-file="$WORK/munged.log" --pid-file="$WORK/munged.pid" --seed-file="$WORK/munged.seed" \
    >"$WORK/munged.out" 2>&1 &
PIDS+=($!)
for _ in $(seq 50); do [ -S "$WORK/munge.socket" ] && break; sleep 0.1; done
munge -n -S "$WORK/munge.socket" | unmunge -S "$WORK/munge.socket" >/dev/null \
    || fail "munged did not start: $(tail -3 "$WORK/munged.out")"

# slurm.conf: this host as the one node, with the CPUs and memory slurmd detects, reached over
# loopback (no name lookup needed)
NODE="$(slurmd -C | grep '^NodeName=')" || fail "slurmd -C could not describe this host"
mkdir -p "$WORK/state" "$WORK/spool"
cat >"$CONF" <<CONFEOF
ClusterName=nldrtest
SlurmctldHost=$(hostname -s)(127.0.0.1)
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$WORK/munge.socket
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$WORK/state
SlurmdSpoolDir=$WORK/spool
SlurmctldPidFile=$WORK/slurmctld.pid
SlurmdPidFile=$WORK/slurmd.pid
SlurmctldLogFile=$WORK/slurmctld.log
SlurmdLogFile=$WORK/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
# finished jobs stay visible to squeue and scontrol this long (s): above the plugin's threshold and the run
MinJobAge=900
$NODE NodeAddr=127.0.0.1 State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONFEOF

# The jobstep executor drops SLURM_* variables (SLURM_CONF too) before its srun inside each job, so the
# configuration must sit where srun looks by default, as on any real cluster.
if [ -e "$SYSCONF" ] || [ -L "$SYSCONF" ]; then
    case "$(readlink "$SYSCONF" || true)" in
        /tmp/nldr-slurm.*) rm -f "$SYSCONF" ;;  # left behind by a killed earlier run
        *) fail "$SYSCONF exists and is not this test's: refusing to replace a real cluster's config" ;;
    esac
fi
mkdir -p /etc/slurm
ln -s "$CONF" "$SYSCONF"
LINKED=1
export SLURM_CONF="$CONF"

slurmctld -D -f "$CONF" >"$WORK/slurmctld.out" 2>&1 &
PIDS+=($!)
slurmd -D -f "$CONF" >"$WORK/slurmd.out" 2>&1 &
PIDS+=($!)
state=""
for _ in $(seq 60); do
    state="$(sinfo -h -o %T 2>/dev/null || true)"
    [ "$state" = idle ] && break
    sleep 0.5
done
[ "$state" = idle ] || fail "the SLURM node is not idle 30 s after start (sinfo says '${state:-nothing}')"
srun -N1 -n1 -t 1 true || fail "srun could not run a one-second job"
echo "SLURM is up: $(sinfo -h -o '%P %D %c CPUs %m MB %T'), MinJobAge $(scontrol show config | awk '/^MinJobAge/ {print $3}') s"

export MPLBACKEND=Agg
if [ "${1:-}" = "--" ]; then
    shift
    echo "running on the cluster: $*"
    "$@"
else
    "$PYTHON" "$REPO/tests/cluster/slurm_pipeline.py" --workdir "$WORK"
fi
