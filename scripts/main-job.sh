#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The main job: install what is missing, build the CLI and library, and run
# `crisp eval` on the bundled default scene (still_life): EEVEE's own curve
# (1, 2, 4, 8, 16 samples), every library method on the 1-sample frames,
# Blender's compositor SMAA, all measured against a 64-sample reference, into
# OUTDIR/report.html (+ results.json, results.csv, images/).
#
# Size chosen for a 2-core machine without a GPU (EEVEE on software OpenGL,
# about 0.075 s for a 1-sample 480x270 frame and 0.035 s per further sample,
# as the report of 2026-12-05 gives them): 480x270, frames 1-16 (seed 000's static protocol:
# 16 frames, then compare, so --warmup 15 keeps frame 16 alone in the means;
# every frame is in the per-frame figures), reference 64 samples; about 2-3
# minutes of rendering. For final figures use --reference-samples 256 and the
# scene's whole range. Rerunning resumes: finished renders and method frames
# are kept.
# Usage: scripts/main-job.sh [OUTDIR]   (default: out/main)
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-out/main}
start=$SECONDS
scripts/install-deps.sh
scripts/build.sh release --target crisp_cli crisp >/dev/null
build/bin/crisp eval --scene still_life --frames 1-16 --warmup 15 --resolution 480x270 --reference-samples 64 \
  --methods none,fxaa,repair,rsaa,taa,taa-improved,phlm -o "$out"
echo "main job finished in $((SECONDS - start)) s"
echo "report: $(realpath "$out/report.html")"
