# SPDX-License-Identifier: Apache-2.0
"""End to end: the hold's release (temporal/hold_release.h) on a real EEVEE render. `crisp eval` on the
bundled light_switch scene (still_life with a second light switched on at frame 41, nothing moves) at
96x54, frames 1-80, against 16-sample references, measuring taa and phlm with their defaults and with
holdRelease=1 (never released). Before the change both settings give the same bits; after the release
(the window closed at frame 64, the second to differ) the released filters come back near the error
they had before the switch, and the never-released ones keep the old light along every edge.
Needs Blender and the built CLI (CRISP_BUILD_DIR)."""

import json
import os
import shutil
import statistics

import pytest

from crisp_test_util import needs_cli_and_blender, run_eval

METHODS = ["taa", "phlm", "taa:holdRelease=1", "phlm:holdRelease=1"]
ARGS = ["--scene", "light_switch", "--resolution", "96x54", "--frames", "1-80", "--reference-samples", "16",
        "--curve", "2", "-q", "--methods", ",".join(METHODS)]

pytestmark = needs_cli_and_blender()


@pytest.fixture(scope="module")
def psnr_by_frame():
    out, _, _ = run_eval(ARGS, "crisp_light_switch_")
    try:
        scene = json.load(open(os.path.join(out, "results.json")))["scenes"][0]
        assert scene["facts"]["moving_objects"] == [] and not scene["facts"]["camera_moves"]
        yield {m["name"]: {f["frame"]: f["psnr"] for f in m["frames"]} for m in scene["methods"]}
    finally:
        shutil.rmtree(out, ignore_errors=True)


def mean_psnr(frames, first, last):
    return statistics.mean(frames[t] for t in range(first, last + 1))


@pytest.mark.parametrize("method", ["taa", "phlm"])
def test_a_light_switched_on_is_taken_in(psnr_by_frame, method):
    released, never = psnr_by_frame[method], psnr_by_frame[method + ":holdRelease=1"]
    before = mean_psnr(released, 17, 40)
    after_released, after_never = mean_psnr(released, 69, 80), mean_psnr(never, 69, 80)
    print("%s: frames 17-40 %.2f dB; frames 69-80 %.2f dB released, %.2f dB never released"
          % (method, before, after_released, after_never))
    # Nothing can be released before the change: the same figures.
    assert all(released[t] == never[t] for t in range(1, 41))
    assert after_released > after_never + 0.5
    assert after_released > before - 0.5
