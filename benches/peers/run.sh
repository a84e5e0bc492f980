#!/usr/bin/env bash
# Side-by-side efficiency of Nimbus vs Cycles and Mitsuba on the peers harness' 64^3 chromatic
# cloud (issue 17). Efficiency = 1 / (one-render relMSE x render seconds).
#
# usage: benches/peers/run.sh PEERS_DIR OUT.csv [NIMBUS_BIN]
#   PEERS_DIR  the folder given to the harness' setup.sh (has venv_mi, venv_bpy, work/)
#   OUT.csv    written here; the EXRs and logs go to OUT's folder, in OUT_without_.csv/
#   NIMBUS_BIN default target/release/nimbus
# env: PEERS_SRC (harness scripts, default /work/shared/peers), ROUNDS (3), THREADS (2),
#      SPP_NB (512, auto), SPP_MIS (512, --tracker spectral-mis), SPP_CY (128), SPP_MI (128)
#
# Each round renders every configuration at seeds 2r and 2r+1, interleaved (seed-major, the
# renderer order rotated each round); the round's seed pair gives the one-render relMSE
# (nimbus_eff.py pair: half the seed-pair relMSE over the fg pixels). seconds = the whole
# process' wall clock (as /usr/bin/time %e); render_s = the time the renderer itself prints.
set -euo pipefail
die() { echo "run.sh: $*" >&2; exit 1; }
[ $# -ge 2 ] || die "usage: $0 PEERS_DIR OUT.csv [NIMBUS_BIN]"
D=$(cd "$1" 2>/dev/null && pwd) || die "no peers dir $1 (run: bash \$PEERS_SRC/setup.sh $1)"
OUT=$2
NB=${3:-target/release/nimbus}
P=${PEERS_SRC:-/work/shared/peers}
ROUNDS=${ROUNDS:-3}; THREADS=${THREADS:-2}
SPP_NB=${SPP_NB:-512}; SPP_MIS=${SPP_MIS:-512}; SPP_CY=${SPP_CY:-128}; SPP_MI=${SPP_MI:-128}
BG="0.25 0.35 0.5"
W=$D/work
for f in "$D/venv_mi/bin/python" "$D/venv_bpy/bin/python" "$W/scene_cloud.json" "$W/cloud64.vdb"; do
  [ -e "$f" ] || die "$f missing: $D is not set up (run: bash $P/setup.sh $D)"
done
for f in json2usda.py nimbus_eff.py cycles_render.py mitsuba_render.py; do
  [ -f "$P/$f" ] || die "$P/$f missing: set PEERS_SRC to the harness folder"
done
[ -x "$NB" ] || die "no nimbus binary $NB (cargo b)"
NB=$(cd "$(dirname "$NB")" && pwd)/$(basename "$NB")
"$NB" render --help | grep -q spectral-mis || die "$NB has no --tracker spectral-mis (stale build?)"
[ -f "$W/cloud.usda" ] || /usr/bin/python3 "$P/json2usda.py" "$W/scene_cloud.json" "$W/cloud.usda"
mkdir -p "$(dirname "$OUT")"
OUT=$(cd "$(dirname "$OUT")" && pwd)/$(basename "$OUT")
IMG=${OUT%.csv}; mkdir -p "$IMG"
MI=$D/venv_mi/bin/python; BPY=$D/venv_bpy/bin/python

# config: name renderer tracker spp
CONFIGS=("nb nimbus auto $SPP_NB" "nbm nimbus spectral-mis $SPP_MIS" "cy cycles - $SPP_CY" "mi mitsuba volpath $SPP_MI")

render() {  # name renderer tracker spp seed -> prints "wall render_s"
  local name=$1 r=$2 t=$3 spp=$4 s=$5 exr=$IMG/$1_$5.exr log=$IMG/$1_$5.log t0 t1 rs
  t0=$(date +%s.%N)
  case $r in
    nimbus)  "$NB" render "$W/cloud.usda" -o "$exr" --spp "$spp" --seed "$s" --threads "$THREADS" \
               --tracker "$t" >"$log" 2>&1 ;;
    cycles)  "$BPY" "$P/cycles_render.py" "$W/scene_cloud.json" "$exr" --spp "$spp" --seed "$s" \
               --threads "$THREADS" >"$log" 2>&1 ;;
    mitsuba) "$MI" "$P/mitsuba_render.py" "$W/scene_cloud.json" "$exr" --spp "$spp" --seed "$s" \
               --threads "$THREADS" >"$log" 2>&1 ;;
  esac || { tail -20 "$log" >&2; die "$name seed $s failed (log $log)"; }
  t1=$(date +%s.%N)
  if [ "$r" = nimbus ]; then rs=$(sed -n 's/.* passes, \([0-9.]*\) s,.*/\1/p' "$log" | tail -1)
  else rs=$(sed -n 's/^time: .* render \([0-9.]*\)s .*/\1/p' "$log" | tail -1); fi
  awk -v a="$t0" -v b="$t1" -v rs="${rs:-NA}" 'BEGIN { printf "%.2f %s\n", b - a, rs }'
}

echo "renderer,tracker,spp,round,seed,seconds,render_s,relMSE,efficiency,efficiency_render_s" >"$OUT"
echo "load before: $(uptime)"
for ((rd = 0; rd < ROUNDS; rd++)); do
  declare -A SEC=() RS=()
  for s in $((2 * rd)) $((2 * rd + 1)); do
    for ((k = 0; k < ${#CONFIGS[@]}; k++)); do
      read -r name r t spp <<<"${CONFIGS[$(((k + rd) % ${#CONFIGS[@]}))]}"
      res=$(render "$name" "$r" "$t" "$spp" "$s")
      read -r "SEC[$name$s]" "RS[$name$s]" <<<"$res"
      echo "round $rd seed $s $name ($r $t $spp spp): ${SEC[$name$s]} s (render ${RS[$name$s]} s)"
    done
  done
  for c in "${CONFIGS[@]}"; do
    read -r name r t spp <<<"$c"
    a=$((2 * rd)); b=$((2 * rd + 1))
    line=$("$MI" "$P/nimbus_eff.py" --bg $BG pair "$IMG/${name}_$a.exr" "$IMG/${name}_$b.exr")
    rel=$(echo "$line" | sed -n 's/.* one render ~ \([0-9.e+-]*\) .*/\1/p')
    [ -n "$rel" ] || die "cannot parse nimbus_eff.py output: $line"
    for s in $a $b; do
      awk -v r="$r" -v t="$t" -v spp="$spp" -v rd="$rd" -v s="$s" -v sec="${SEC[$name$s]}" \
          -v rs="${RS[$name$s]}" -v rel="$rel" 'BEGIN {
        e2 = (rs == "NA") ? "NA" : sprintf("%.4g", 1 / (rel * rs))
        printf "%s,%s,%d,%d,%d,%.2f,%s,%s,%.4g,%s\n", r, t, spp, rd, s, sec, rs, rel, 1 / (rel * sec), e2 }' >>"$OUT"
    done
  done
  echo "round $rd done; load: $(uptime)"
done

echo "== medians over $ROUNDS rounds ($OUT) =="
"$MI" - "$OUT" <<'EOF'
import csv, statistics as st, sys
rows = list(csv.DictReader(open(sys.argv[1])))
keys = list(dict.fromkeys((r["renderer"], r["tracker"], r["spp"]) for r in rows))
med = {}
print(f"{'renderer':8} {'tracker':13} {'spp':>4} {'seconds':>8} {'render_s':>8} {'relMSE':>10} {'eff':>7} {'eff(render_s)':>13}")
for k in keys:
    g = [r for r in rows if (r["renderer"], r["tracker"], r["spp"]) == k]
    m = lambda c: st.median(float(r[c]) for r in g if r[c] != "NA")
    med[k[:2]] = e = m("efficiency")
    print(f"{k[0]:8} {k[1]:13} {k[2]:>4} {m('seconds'):8.2f} {m('render_s'):8.2f} {m('relMSE'):10.4e} {e:7.2f} {m('efficiency_render_s'):13.2f}")
cy = med.get(("cycles", "-"))
for t in ("auto", "spectral-mis"):
    if cy and ("nimbus", t) in med:
        print(f"Nimbus {t} efficiency / Cycles efficiency = {med[('nimbus', t)] / cy:.2f}")
EOF
echo "== bias: all Nimbus seeds averaged vs all Mitsuba / Cycles seeds (nimbus_eff.py bias) =="
n=$((2 * ROUNDS - 1)); join() { local s o=; for s in $(seq 0 $n); do o+="$IMG/$1_$s.exr,"; done; echo "${o%,}"; }
for a in nb nbm; do
  for ref in mi cy; do
    echo "-- $a vs $ref"
    "$MI" "$P/nimbus_eff.py" --bg $BG bias "$(join $a)" "$(join $ref)" | grep -E 'all:|ratio vs each'
  done
done
echo "-- cy vs mi"
"$MI" "$P/nimbus_eff.py" --bg $BG bias "$(join cy)" "$(join mi)" | grep -E 'all:'
echo "load after: $(uptime)"
