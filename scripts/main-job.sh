#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The main job on the bundled default scene. Until the Blender evaluation
# (`crisp eval`) lands, the default scene is the analytic test chart: every
# spatial method filters its 1-sample image, is measured against the exact
# 16x16 box-filtered reference (whole image and edge pixels) and timed, and
# the figures go into a self-contained HTML report.
# Usage: scripts/main-job.sh [OUTDIR]   (default: out/main)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/main}
scripts/install-deps.sh
scripts/build.sh release >/dev/null
crisp=build/bin/crisp
mkdir -p "$out"
"$crisp" synth -o "$out/scene" --size 480x270 >/dev/null
methods=(none fxaa repair)
for m in "${methods[@]}"; do
  "$crisp" filter -q --method "$m" --png "$out/scene/chart_1spp.exr" -o "$out/$m"
  "$crisp" compare -q --reference "$out/scene/chart_reference.exr" --test "$out/$m/chart_1spp.exr" \
    --json "$out/$m/all.json" --maps "$out/$m/maps" >/dev/null
  "$crisp" compare -q --reference "$out/scene/chart_reference.exr" --test "$out/$m/chart_1spp.exr" \
    --mask "$out/scene/chart_edges.exr" --json "$out/$m/edges.json" >/dev/null
done
/usr/bin/python3 tools/spatial_report.py "$out" "${methods[@]}"
echo "report: $(realpath "$out/report.html")"
