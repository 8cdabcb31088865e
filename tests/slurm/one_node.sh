#!/usr/bin/env bash
# A real Slurm run of `radbake shard`: brings up a one-node Slurm cluster on
# 127.0.0.1 (munge, slurmctld, slurmd; installs slurm-wlm and munge with
# apt where missing), plans a sharded bake, submits it with the script
# `radbake shard slurm` prints (a job array per phase, afterok between
# phases), waits for the final merge and checks that its outputs are
# byte-identical to `radbake bake`'s.
#
#   tests/slurm/one_node.sh [SCENE [SHARDS]]    # default: the Cornell box, 4 shards
#
# Exit status: 0 the sharded bake matched; 1 it did not (or failed); 77
# Slurm could not be installed or started on this machine (nothing tested).
# Needs root (it writes /etc/slurm and starts daemons) and a built
# target/release/radbake (or RADBAKE=path). Stops the daemons it started.
set -euo pipefail
cd "$(dirname "$0")/../.."
scene=${1:-scenes/cornell_box.gltf}
shards=${2:-4}
radbake=${RADBAKE:-$PWD/target/release/radbake}
t0=$(date +%s.%N)
say() { printf '[%6.1f s] %s\n' "$(awk -v a="$(date +%s.%N)" -v b="$t0" 'BEGIN { print a - b }')" "$*"; }

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
  say "installing slurm-wlm and munge"
  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge >/dev/null) \
    || { echo "cannot install slurm-wlm and munge" >&2; exit 77; }
fi

# munge: one key, one daemon.
if [ ! -s /etc/munge/munge.key ]; then
  (mungekey --create 2>/dev/null || create-munge-key -f) >/dev/null
fi
chown munge:munge /etc/munge/munge.key && chmod 400 /etc/munge/munge.key
mkdir -p /run/munge && chown munge:munge /run/munge
pgrep -x munged >/dev/null || runuser -u munge -- munged || { echo "munged does not start" >&2; exit 77; }

# Slurm: this host as controller and only node, no cgroups, no accounting.
host=$(hostname -s)
mkdir -p /etc/slurm /var/spool/slurmd /var/spool/slurmctld /var/log/slurm
cat > /etc/slurm/slurm.conf <<CONF
ClusterName=radbake
SlurmctldHost=$host(127.0.0.1)
AuthType=auth/munge
SlurmUser=root
SlurmdUser=root
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
MinJobAge=600
SlurmctldPidFile=/run/slurmctld.pid
SlurmdPidFile=/run/slurmd.pid
SlurmdSpoolDir=/var/spool/slurmd
StateSaveLocation=/var/spool/slurmctld
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) RealMemory=$(( $(free -m | awk '/Mem:/ {print $2}') * 9 / 10 )) State=UNKNOWN
PartitionName=main Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
started=""
cleanup() {
  if [ -n "$started" ]; then
    pkill -x slurmd || true
    pkill -x slurmctld || true
  fi
}
trap cleanup EXIT
pkill -x slurmd 2>/dev/null || true
pkill -x slurmctld 2>/dev/null || true
sleep 0.5
{ slurmctld -c && slurmd -c && started=yes; } || { echo "slurm daemons do not start" >&2; exit 77; }
for _ in $(seq 60); do
  sinfo -h -o '%t' 2>/dev/null | grep -qE '^idle' && break
  sleep 0.5
done
sinfo -h -o '%t' | grep -qE '^idle' || { echo "slurm did not come up" >&2; tail -20 /var/log/slurm/*.log >&2; exit 77; }
say "slurm up: $(sinfo -h -o '%N %c CPUs %t')"

work=$(mktemp -d /tmp/radbake-slurm-XXXX)
say "one-machine bake of $scene"
"$radbake" bake "$scene" --out "$work/reference" -q
say "plan: $shards shards"
"$radbake" shard plan "$scene" --out "$work/sharded" --shards "$shards" -q
"$radbake" shard slurm "$work/sharded" --radbake "$radbake" > "$work/submit.sh"
last=$(bash "$work/submit.sh") || { echo "sbatch refused the jobs" >&2; exit 77; }
say "submitted; final merge is job $last"
state=""
for _ in $(seq 900); do  # 3 minutes at most
  state=$(scontrol show job "$last" -o 2>/dev/null | grep -o 'JobState=[A-Z_]*' | cut -d= -f2 || true)
  reason=$(scontrol show job "$last" -o 2>/dev/null | grep -o 'Reason=[A-Za-z_]*' | cut -d= -f2 || true)
  case "$state" in
    COMPLETED) break ;;
    FAILED|CANCELLED|TIMEOUT|NODE_FAIL) break ;;
  esac
  [ "$reason" = DependencyNeverSatisfied ] && { state=DEPENDENCY_FAILED; break; }
  sleep 0.2
done
if [ "$state" != COMPLETED ]; then
  if ! ls "$work"/sharded/shards/slurm-*.log >/dev/null 2>&1; then
    # Not one job started: Slurm cannot run jobs on this machine.
    echo "Slurm ran no job here (job $last: ${state:-unknown})" >&2
    exit 77
  fi
  echo "the sharded bake did not complete: job $last ${state:-still pending}" >&2
  tail -n 5 "$work"/sharded/shards/slurm-*.log >&2 || true
  exit 1
fi
say "final merge completed"
same=0
for f in "$work/reference"/*; do
  name=$(basename "$f")
  [ "$name" = report.json ] && continue
  cmp -s "$f" "$work/sharded/$name" || { echo "DIFFERS: $name" >&2; exit 1; }
  same=$((same + 1))
done
say "$same output files byte-identical to radbake bake; jobs run by Slurm: $(ls "$work"/sharded/shards/slurm-*.log | wc -l)"
rm -rf "$work"
