#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, for running and testing the sharded studies
# (deploy/slurm/study.sbatch) for real. No systemd: munged and the two Slurm daemons are
# started directly. Needs root and Debian's slurm-wlm and munge packages (installed here
# when missing). Idempotent: a second call finds the node up and returns.
#   bash deploy/slurm/local_cluster.sh          # start; `sinfo` then shows the node idle
#   bash deploy/slurm/local_cluster.sh stop     # stop the daemons
set -euo pipefail

# Whether a daemon runs (a zombie left by a killed parent does not count).
running() {
  ps -C "$1" -o stat= 2>/dev/null | grep -qv '^Z'
}

if [ "${1:-}" = stop ]; then
  pkill -x slurmd || true
  pkill -x slurmctld || true
  pkill -x munged || true
  exit 0
fi

if ! command -v slurmctld >/dev/null 2>&1 || ! command -v munged >/dev/null 2>&1; then
  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq slurm-wlm munge) >/dev/null
fi

host=$(hostname -s)
cpus=$(nproc)
# Slurm refuses a node that claims more memory than it has: give it what is free, in MB.
mem=$(awk '/MemTotal/ {print int($2 / 1024 * 0.9)}' /proc/meminfo)

# munge: a key owned by user munge, mode 400, and munged running as that user.
install -d -o munge -g munge -m 700 /etc/munge /var/lib/munge /var/log/munge
install -d -o munge -g munge -m 755 /run/munge
if [ ! -s /etc/munge/munge.key ]; then
  dd if=/dev/urandom of=/etc/munge/munge.key bs=1024 count=1 status=none
fi
chown munge:munge /etc/munge/munge.key
chmod 400 /etc/munge/munge.key
if ! running munged; then
  runuser -u munge -- /usr/sbin/munged
fi

install -d /var/spool/slurmctld /var/spool/slurmd /var/log/slurm /run/slurm
conf=/etc/slurm/slurm.conf
mkdir -p /etc/slurm
cat > "$conf.new" <<CONF
# Written by keyshape-lab's deploy/slurm/local_cluster.sh: one node, no accounting.
ClusterName=kslab
SlurmctldHost=$host
SlurmUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
ReturnToService=2
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldPidFile=/run/slurm/slurmctld.pid
SlurmdPidFile=/run/slurm/slurmd.pid
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
MpiDefault=none
NodeName=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=main Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
mv "$conf.new" "$conf"

if ! running slurmctld; then
  /usr/sbin/slurmctld
fi
if ! running slurmd; then
  /usr/sbin/slurmd
fi

# Wait (at most a minute) for the node to come up idle (or mixed/allocated, if jobs run).
deadline=$((SECONDS + 60))
while [ "$SECONDS" -lt "$deadline" ]; do
  state=$(timeout 5 sinfo -h -n "$host" -o %t 2>/dev/null || true)
  case "$state" in
    idle* | mix* | alloc*) sinfo; exit 0 ;;
  esac
  sleep 1
done
echo "error: the Slurm node $host did not come up within a minute; see /var/log/slurm/" >&2
timeout 5 sinfo >&2 || true
tail -n 20 /var/log/slurm/slurmctld.log /var/log/slurm/slurmd.log >&2 || true
exit 1
