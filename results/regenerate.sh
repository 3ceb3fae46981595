#!/usr/bin/env bash
# Writes every result in results/ again with the installed esail_opt, one command at a time
# (the benches are separate: results/bench/README.md names each one's command).
# Usage: bash results/regenerate.sh   (from the repository's top folder, in its venv)
set -u
cd "$(dirname "$0")/.."
status=0
run() { echo "+ $*" >&2; "$@" || { echo "exit $? from: $*" >&2; status=1; }; }

for p in earth_bennu_rendezvous earth_mars_2035 earth_mars_low_thrust earth_mars_min_time \
         earth_mars_window earth_mars_window_planar earth_venus_low_thrust earth_venus_min_ac \
         earth_venus_min_ac_planar earth_venus_min_time mercury_departure orbit_raising_10yr \
         spiral_out_5au; do
  run esail-opt solve "problems/$p.py"
done
run esail-opt solve problems/earth_mars_coast.py --polish
run esail-opt solve problems/earth_mars_min_ac.py --polish
run esail-opt solve problems/earth_mars_min_ac_planar.py --polish
run esail-opt robust results/earth_mars_min_ac --runs 1000 --margin 0,0.1,0.5
for p in earth_mars_low_thrust earth_mars_min_time earth_venus_low_thrust earth_venus_min_time; do
  run esail-opt solve "problems/$p.py" --polish --out "results/${p}_polished"
done
run esail-opt search problems/earth_mars_min_time.py --extra-revolutions 2 \
    --out results/earth_mars_min_time_search
run esail-opt search problems/earth_mars_rendezvous.py --extra-revolutions 2 \
    --out results/earth_mars_rendezvous_search
run esail-opt sweep problems/earth_mars_min_time.py --param ac_mm_s2=0.2:2.0:10 \
    --out results/sweep_earth_mars_ac
run esail-opt porkchop problems/earth_mars_window.py --depart 2030-01-01:2033-01-01:25 \
    --out results/earth_mars_window_porkchop
run esail-opt porkchop problems/earth_venus_min_ac.py --depart 2031-01-01:2032-06-01:6 \
    --tof 550:850:4 --out results/earth_venus_min_ac_porkchop
for fig in fig2 fig3 fig4 fig5 fig6 fig7 convergence; do
  run esail-opt reproduce "$fig"
done
exit $status
