#!/usr/bin/env bash
# Regenerates the figures in docs/figures/ that softrod itself draws (the viewer's screenshots
# come from benchmarks/bench_viewer.py --figures). Needs softrod installed (pip install -e .).
# Run from anywhere: bash scripts/make_doc_figures.sh
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
SOFTROD=("$PY" -m softrod.cli)
out=docs/figures
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

echo "== softrod demo: $out/demo_shapes.png"
"${SOFTROD[@]}" demo --out-dir "$tmp/demo" >/dev/null
cp "$tmp/demo/shapes.png" "$out/demo_shapes.png"

echo "== paper 002's experiments: $out/compare_paper002_fig{5,6,7}.png"
"${SOFTROD[@]}" compare --experiments iii,a --figure "$out/compare_paper002_fig5.png" >/dev/null
"${SOFTROD[@]}" compare --experiments i --figure "$out/compare_paper002_fig6.png" >/dev/null
"${SOFTROD[@]}" compare --experiments ii --figure "$out/compare_paper002_fig7.png" >/dev/null

echo "== mode shapes of the 130 mm actuator: $out/modes_spa130.png"
"${SOFTROD[@]}" modes spa_three_chamber_130mm -p 30kPa,5kPa,45kPa --count 4 \
    --figure "$out/modes_spa130.png" >/dev/null

echo "== mode shapes of the two-rod platform: $out/modes_two_spa_platform.png"
"$PY" -c "
import matplotlib; matplotlib.use('Agg')
import softrod
sol = softrod.solve_system('two_spa_platform', [[20e3, 5e3, 3e3], [2e3, 15e3, 10e3]])
sol.linearise(nodes=6).plot_modes(3, '$out/modes_two_spa_platform.png')
"

echo "== PCC model vs rod: $out/pcc_*.png"
"$PY" examples/pcc_vs_cosserat.py "$out" >/dev/null
echo "done"
