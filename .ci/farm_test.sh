#!/usr/bin/env bash
# Farm integration test (issue 16), run by .ci/run after `cargo t` built
# target/release/nimbus:
#  1. Open Job Description: `nimbus farm openjd` writes a template for 2 frames x 2 tiles
#     of scenes/cloud, denoised (issue 48: the tiles are not, the merge step denoises
#     each frame); `openjd check` validates it and `openjd run` runs the render and
#     merge steps locally.
#  2. Slurm: a real slurmctld + slurmd on loopback (as root, auth/none), `nimbus farm
#     slurm --submit` of 2 frames x 4 tiles, denoised too (the merge jobs denoise);
#     one render task is killed mid-render and requeued; the merge jobs (afterany)
#     must end with both frames complete.
# Both frames must equal one-machine renders bit for bit in every channel. The job's
# folder and output paths hold a space, quotes and `$` (quoting must survive). Exits
# non-zero on any failure; never skips.
set -euo pipefail
cd "$(dirname "$0")/.."
root=$PWD
nimbus="$root/target/release/nimbus"
[ -x "$nimbus" ] || { echo "farm test: $nimbus is not built" >&2; exit 1; }
work=$(mktemp -d)
odd="$work/shot dir 'q' \$HOME"
mkdir -p "$odd"
flags=(--res 48x36 --spp 24 --seed 7 --denoise)

# Bitwise equality of every channel of two EXRs (OpenEXR's Python bindings).
same() {
    "$py" - "$1" "$2" <<'EOF'
import OpenEXR, sys
a, b = OpenEXR.InputFile(sys.argv[1]), OpenEXR.InputFile(sys.argv[2])
ca, cb = sorted(a.header()['channels']), sorted(b.header()['channels'])
assert ca == cb, (ca, cb)
bad = [c for c in ca if a.channel(c) != b.channel(c)]
assert not bad, f"{sys.argv[1]} differs from {sys.argv[2]} in {bad}"
print(f"equal: {sys.argv[1]} ({len(ca)} channels)")
EOF
}

venv="$work/venv"
python3 -m venv "$venv"
"$venv/bin/python" -m pip install --quiet --disable-pip-version-check openjd-cli OpenEXR numpy
py="$venv/bin/python"

# One-machine reference renders of frames 1 and 2 (the Slurm tasks take more samples,
# so that one can be killed while it renders).
slow=(--res 48x36 --spp 800 --seed 7 --denoise)
for f in 1 2; do
    "$nimbus" render scenes/cloud/cloud.usda -o "$work/ref.$f.exr" --frame $f "${flags[@]}" 2>/dev/null
    "$nimbus" render scenes/cloud/cloud.usda -o "$work/slow.$f.exr" --frame $f "${slow[@]}" 2>/dev/null
done

echo "== Open Job Description"
"$nimbus" farm openjd scenes/cloud/cloud.usda -o "$odd/ojd.####.exr" --frames 1-2 --tiles 2 \
    --dir "$odd/ojd-job" -- "${flags[@]}"
"$venv/bin/openjd" check "$odd/ojd-job/job.template.json"
"$venv/bin/openjd" run "$odd/ojd-job/job.template.json" --step Merge --run-dependencies >"$work/openjd.log" 2>&1 \
    || { tail -40 "$work/openjd.log"; exit 1; }
same "$odd/ojd.0001.exr" "$work/ref.1.exr"
same "$odd/ojd.0002.exr" "$work/ref.2.exr"

echo "== Slurm"
export DEBIAN_FRONTEND=noninteractive
if ! command -v slurmctld >/dev/null; then
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends slurm-wlm >/dev/null
fi
host=$(hostname -s)
sl="$work/slurm"
mkdir -p "$sl"/{state,spool,log}
export SLURM_CONF="$sl/slurm.conf"
cat >"$SLURM_CONF" <<EOF
ClusterName=nimbus-ci
SlurmctldHost=$host(127.0.0.1)
SlurmUser=root
SlurmdUser=root
AuthType=auth/none
CredType=cred/none
StateSaveLocation=$sl/state
SlurmdSpoolDir=$sl/spool
SlurmctldLogFile=$sl/log/slurmctld.log
SlurmdLogFile=$sl/log/slurmd.log
SlurmctldPidFile=$sl/slurmctld.pid
SlurmdPidFile=$sl/slurmd.pid
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MpiDefault=none
MailProg=/bin/true
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
ReturnToService=2
NodeName=$host NodeAddr=127.0.0.1 CPUs=2 RealMemory=1000 State=UNKNOWN
PartitionName=ci Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
slurmctld -D -i >"$sl/log/ctld.out" 2>&1 &
ctld=$!
slurmd -D >"$sl/log/d.out" 2>&1 &
sd=$!
trap 'kill $ctld $sd 2>/dev/null || true; wait $ctld $sd 2>/dev/null || true' EXIT
for i in $(seq 1 60); do
    sinfo -h -o %t 2>/dev/null | grep -q idle && break
    sleep 0.5
done
sinfo -h -o '%P %t %D' | grep -q idle || { cat "$sl"/log/*; echo "slurm did not come up" >&2; exit 1; }

ids=$("$nimbus" farm slurm scenes/cloud/cloud.usda -o "$odd/slurm.####.exr" --frames 1-2 --tiles 4 \
    --dir "$odd/slurm-job" --submit -- "${slow[@]}")
render=${ids% *}
merge=${ids#* }
echo "render array $render, merge array $merge"

# Kill render task 5 (frame 2, tile 1) once it runs, then requeue it.
victim="${render}_5"
for i in $(seq 1 240); do
    state=$(squeue -h -j "$victim" -o %T 2>/dev/null || true)
    [ "$state" = RUNNING ] && break
    sleep 0.25
done
[ "$state" = RUNNING ] || { squeue; echo "task $victim never ran" >&2; exit 1; }
sleep 0.5
pkill -KILL -f "farm task --job .* --index 5$" || { echo "no task 5 process to kill" >&2; exit 1; }
for i in $(seq 1 40); do
    squeue -h -j "$victim" -o %T 2>/dev/null | grep -q RUNNING || break
    sleep 0.25
done
scontrol requeue "$victim" 2>/dev/null || true
scontrol update JobId="$victim" StartTime=now 2>/dev/null || true
echo "killed and requeued $victim"

# Wait (bounded) until nothing of either array is queued or running.
deadline=$((SECONDS + 150))
while squeue -h -j "$render,$merge" 2>/dev/null | grep -q .; do
    if [ $SECONDS -gt $deadline ]; then squeue; cat "$odd"/slurm-job/logs/* | tail -40; echo "timeout" >&2; exit 1; fi
    # A requeued task waits for its begin time; release it at once.
    for j in $(squeue -h -j "$render" -t PENDING -o %i 2>/dev/null); do
        scontrol update JobId="$j" StartTime=now 2>/dev/null || true
    done
    sleep 1
done
grep -l "killed\|Killed\|error" "$odd"/slurm-job/logs/render-* 2>/dev/null | head -3 || true
# Denoised by the merge jobs (the tiles were not), as the one-machine renders were.
grep -q "denoised in" "$odd"/slurm-job/logs/merge-* || { tail -20 "$odd"/slurm-job/logs/merge-*; echo "a merge job did not denoise" >&2; exit 1; }
same "$odd/slurm.0001.exr" "$work/slow.1.exr" || { tail -20 "$odd"/slurm-job/logs/*; exit 1; }
same "$odd/slurm.0002.exr" "$work/slow.2.exr" || { tail -20 "$odd"/slurm-job/logs/*; exit 1; }
# The killed task really ran twice (a second start after the kill).
starts=$(grep -c "" "$odd"/slurm-job/logs/render-"${render}"_5.log 2>/dev/null || echo 0)
echo "task 5 log lines: $starts"
echo "farm test: 2 passed, 0 failed"
rm -rf "$work"
