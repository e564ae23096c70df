# SPDX-License-Identifier: Apache-2.0
"""Chunked processing for render farms (issue 8) on real Blender renders: spinning_cube at 64x36,
frames 1-8, rendered once by `crisp render --method taa-improved` (whose passes every method can
read; its filtered/ is the sequential taa-improved result of the add-on's filter path).

  * `crisp filter --frames A-B --preroll N` over the inputs: chunks whose pre-roll reaches back to
    the first frame equal one sequential run bit for bit, for taa, taa-improved, phlm and fxaa (a
    spatial method needs no pre-roll at all, and reads none when given one); a shorter pre-roll is not bit-exact (the history is
    younger; docs/farm.md has the measured table) but closer to sequential than none;
  * `--resume` starts at the first missing output, leaves complete outputs untouched and, with its
    pre-roll taken before that frame, writes what an uninterrupted run writes; after a failed run it
    starts at the failure, and it makes again the outputs of an input changed since (and, for a temporal
    method, later ones up to the next gap or cut; a spatial method keeps every complete output);
  * `crisp render --frames A-B --preroll N --shot S-E`: chunks rendered out of order, two of them at
    the same time, into one output folder equal the sequential render; pre-roll frames never reach
    input/ or filtered/; a resumed chunk reads its pre-roll from input/ instead of rendering it again;
  * with Film > Transparent (a .blend of spinning_cube), the temporal methods' filtered alpha too: full
    pre-roll chunks of `crisp filter` and `crisp render` equal the sequential run, colour and alpha;
  * the Flamenco job type (flamenco/crisp-render.js, compiled under Node.js): its tasks' commands, run
    in reverse order, equal the sequential render.

`python3 tests/python/test_chunking.py --measure [OUTDIR] [--scene NAME:FRAMES:CHUNK_START]...
[--prerolls 0,1,2,...]` prints the pre-roll table of docs/farm.md (chunked against sequential for each
pre-roll length, per method, on moving and still scenes).
Needs Blender and the built CLI and library (CRISP_BUILD_DIR)."""

import importlib.util
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from crisp_test_util import (CRISP, LIBRARY, SOURCE, Lib,  # noqa: E402  (Lib reads EXRs through libcrisp's C API)
                             addon_with_spinning_cube_ending, psnr)

SIZE = "64x36"
SHOT = (1, 8)
TEMPORAL = ("taa", "taa-improved", "phlm")

pytestmark = [
    pytest.mark.skipif(not os.path.isfile(CRISP), reason="crisp CLI not built at %s" % CRISP),
    pytest.mark.skipif(not os.path.isfile(LIBRARY), reason="libcrisp not built at %s" % LIBRARY),
    pytest.mark.skipif(shutil.which("blender") is None, reason="blender not installed"),
]


def crisp(*args, ok=True):
    p = subprocess.run([CRISP, *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                       timeout=300)
    if ok:
        assert p.returncode == 0, p.stderr[-3000:] + p.stdout[-2000:]
    return p


def frame(f, ext=".exr"):
    return "frame_%04d%s" % (f, ext)


def render(out, frames, method="taa-improved", *extra):
    return crisp("render", "--scene", "spinning_cube", "--resolution", SIZE, "--frames", "%d-%d" % frames,
                 "--method", method, "--quiet", "-o", out, *extra)


@pytest.fixture(scope="module")
def lib():
    return Lib()


@pytest.fixture(scope="module")
def shot(tmp_path_factory):
    out = tmp_path_factory.mktemp("sequential")
    p = render(out, SHOT)
    assert p.stdout == "", p.stdout[-2000:]  # --quiet: no progress from Blender or the driver
    assert p.stderr == "", p.stderr[-2000:]  # nor Blender's notes (EGL's fallback) on success
    inputs = [str(out / "input" / frame(f)) for f in range(SHOT[0], SHOT[1] + 1)]
    assert all(os.path.isfile(p) for p in inputs)
    return out, inputs


def filter_chunks(inputs, method, out, chunks, preroll, *extra):
    for a, b in chunks:
        crisp("filter", "--method", method, "--frames", "%d-%d" % (a, b), "--preroll", preroll, "--quiet",
              *extra, "-o", out, *inputs)


def max_diff(lib, a_dir, b_dir, frames):
    """Largest |a - b| of any colour channel over the frames (0.0: bit-identical colours)."""
    def colour(d, f):
        return lib.color(os.path.join(d, frame(f)))
    return max(float(np.max(np.abs(colour(a_dir, f) - colour(b_dir, f)))) for f in frames)


def mtimes(d, frames=range(1, 9)):
    """The modification times of the frames' outputs in folder d."""
    return {f: os.stat(d / frame(f)).st_mtime_ns for f in frames}


def rewritten(before, d):
    """The frames of `before` (mtimes) whose output in d has been written since."""
    now = mtimes(d, before)
    return [f for f in before if now[f] != before[f]]


def mean_psnr(lib, a_dir, b_dir, frames):
    return np.mean([psnr(lib.color(os.path.join(a_dir, frame(f))), lib.color(os.path.join(b_dir, frame(f))))
                    for f in frames])


@pytest.mark.parametrize("method", TEMPORAL + ("fxaa",))
def test_filter_chunks_equal_sequential(shot, lib, tmp_path, method):
    _, inputs = shot
    seq, full, short = tmp_path / "seq", tmp_path / "full", tmp_path / "short"
    crisp("filter", "--method", method, "--quiet", "-o", seq, *inputs)
    chunks = [(1, 3), (4, 6), (7, 8)]
    # Every chunk's pre-roll reaches frame 1; a spatial method has no history and needs none.
    filter_chunks(inputs, method, full, chunks, 0 if method == "fxaa" else 6)
    frames = range(1, 9)
    assert sorted(os.listdir(full)) == [".crisp"] + [frame(f) for f in frames]  # .crisp: the outputs' stamps
    assert max_diff(lib, seq, full, frames) == 0.0
    if method == "fxaa":
        return
    # A pre-roll short of frame 1 leaves the history younger than a sequential run's: not bit-exact
    # (docs/farm.md has the measured table), but closer to sequential than a cold chunk.
    cold = tmp_path / "cold"
    filter_chunks(inputs, method, short, [(5, 8)], 2)
    filter_chunks(inputs, method, cold, [(5, 8)], 0)
    # Pre-roll inputs 3, 4 not written.
    assert sorted(os.listdir(short)) == [".crisp"] + [frame(f) for f in range(5, 9)]
    assert max_diff(lib, seq, cold, range(5, 9)) > 0.0  # history matters
    assert mean_psnr(lib, seq, short, range(5, 9)) > mean_psnr(lib, seq, cold, range(5, 9))


def test_a_spatial_method_reads_no_preroll_frame(shot, lib, tmp_path):
    """--preroll warms a temporal history; a spatial chunk given one reads none of those inputs (as
    the add-on's render renders none): a truncated pre-roll input stops taa, naming it, not fxaa."""
    out, _ = shot
    folder = tmp_path / "input"
    shutil.copytree(out / "input", folder)
    inputs = [str(folder / frame(f)) for f in range(SHOT[0], SHOT[1] + 1)]
    broken = folder / frame(2)
    with open(broken, "r+b") as f:
        f.truncate(os.path.getsize(broken) // 2)
    seq, spatial, temporal = tmp_path / "seq", tmp_path / "spatial", tmp_path / "temporal"
    crisp("filter", "--method", "fxaa", "--frames", "4-6", "--quiet", "-o", seq, *inputs)
    p = crisp("filter", "--method", "fxaa", "--frames", "4-6", "--preroll", "3", "-o", spatial, *inputs)
    assert "frame_0002" not in p.stderr + p.stdout and "pre-roll" not in p.stderr + p.stdout
    assert sorted(os.listdir(spatial)) == [".crisp"] + [frame(f) for f in range(4, 7)]
    assert max_diff(lib, seq, spatial, range(4, 7)) == 0.0
    p = crisp("filter", "--method", "taa", "--frames", "4-6", "--preroll", "3", "-o", temporal, *inputs, ok=False)
    assert p.returncode != 0 and str(broken) in p.stderr, p.stderr
    assert not temporal.exists()  # no output: the folder the run made is removed again


def test_filter_resume_at_first_missing_output(shot, lib, tmp_path):
    _, inputs = shot
    seq, out = tmp_path / "seq", tmp_path / "out"
    crisp("filter", "--method", "taa", "--quiet", "--png", "-o", seq, *inputs)
    filter_chunks(inputs, "taa", out, [(1, 8)], 0, "--png")
    # An interrupted run: outputs are renamed into place, so 1-4 are whole, 5 lost its PNG, 6-8 missing.
    os.remove(out / frame(5, ".png"))
    for f in (6, 7, 8):
        for ext in (".exr", ".png"):
            os.remove(out / frame(f, ext))
    kept = {f: os.stat(out / frame(f)).st_mtime_ns for f in range(1, 5)}
    p = crisp("filter", "--method", "taa", "--frames", "1-8", "--preroll", "8", "--resume", "--png", "-o", out, *inputs)
    assert "1/8 frame_0001 (pre-roll)" in p.stderr and "4/8 frame_0004 (pre-roll)" in p.stderr, p.stderr
    assert "5/8 frame_0005 (" in p.stderr and "frame_0005 (pre-roll)" not in p.stderr  # written again
    assert {f: os.stat(out / frame(f)).st_mtime_ns for f in range(1, 5)} == kept
    assert max_diff(lib, seq, out, range(1, 9)) == 0.0  # pre-roll 8 before frame 5 reaches frame 1
    again = crisp("filter", "--method", "taa", "--frames", "1-8", "--resume", "--png", "-o", out, *inputs)
    assert "nothing to do" in again.stdout
    # The outputs found are taa's: a resume with other parameters, or another method, makes them again.
    variant = tmp_path / "variant"
    crisp("filter", "--method", "taa", "--set", "feedbackMin=0.5", "--quiet", "-o", variant, *inputs)
    p = crisp("filter", "--method", "taa", "--set", "feedbackMin=0.5", "--resume", "--quiet", "-o", out, *inputs)
    assert "frame_0001' was made with other settings" in p.stderr, p.stderr
    assert max_diff(lib, variant, out, range(1, 9)) == 0.0
    # The same value spelled otherwise is the same setting: the outputs stay (each spelling made every
    # frame again, as other settings).
    for spelling in ("0.50", "5e-1", "+0.5"):
        p = crisp("filter", "--method", "taa", "--set", "feedbackMin=" + spelling, "--resume", "-o", out, *inputs)
        assert "nothing to do" in p.stdout and "other settings" not in p.stderr, (spelling, p.stderr)
    # A partial run with another method leaves the other frames' stamps: a resume makes them again too.
    crisp("filter", "--method", "fxaa", "--frames", "3-3", "--quiet", "-o", out, *inputs)
    p = crisp("filter", "--method", "fxaa", "--resume", "--quiet", "-o", out, *inputs)
    assert "frame_0001' was made with other settings" in p.stderr, p.stderr
    fxaa = tmp_path / "fxaa"
    crisp("filter", "--method", "fxaa", "--quiet", "-o", fxaa, *inputs)
    assert max_diff(lib, fxaa, out, range(1, 9)) == 0.0


def test_filter_resume_after_a_failed_run_and_a_changed_input(shot, lib, tmp_path):
    """Each output's stamp names its input and sidecar (size, modification time) and, for a temporal
    method, every input its history went through (from the chunk's first pre-roll frame on). So
    after a run that failed part-way, a resume starts where the outputs no longer match the inputs;
    an input or sidecar changed since makes its own output and every later one of a temporal
    method again (a spatial method's only its own), also when it is in a chunk's pre-roll."""
    source, _ = shot
    folder = tmp_path / "input"
    shutil.copytree(source / "input", folder)  # copy2: sizes and times kept
    inputs = [str(folder / frame(f)) for f in range(SHOT[0], SHOT[1] + 1)]
    out, seq = tmp_path / "out", tmp_path / "seq"
    crisp("filter", "--method", "taa", "--quiet", "-o", out, *inputs)  # an earlier run

    # Frame 3 rendered again (here: a new modification time) and frame 5 broken: the next run makes
    # 1-4 and fails at 5; outputs 5-8 stay (never lost), made after the old frame 3.
    st = os.stat(folder / frame(3))
    os.utime(folder / frame(3), ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    whole = tmp_path / "frame_0005.exr"
    shutil.copy2(folder / frame(5), whole)
    with open(folder / frame(5), "r+b") as f:
        f.truncate(os.path.getsize(whole) // 2)
    before = mtimes(out)
    p = crisp("filter", "--method", "taa", "--quiet", "-o", out, *inputs, ok=False)
    assert p.returncode != 0 and frame(5) in p.stderr, p.stderr
    assert rewritten(before, out) == [1, 2, 3, 4]
    # Frame 5 mended (its old size and time back): the resume starts at 5, not "nothing to do", and
    # (no --preroll needed) re-reads from frame 1, so it writes what one run writes.
    shutil.copy2(whole, folder / frame(5))
    before = mtimes(out)
    p = crisp("filter", "--method", "taa", "--resume", "-o", out, *inputs)
    assert "1/8 frame_0001 (pre-roll)" in p.stderr, p.stderr
    assert "frame_0005' was made after other inputs before it" in p.stderr, p.stderr
    assert rewritten(before, out) == [5, 6, 7, 8]
    crisp("filter", "--method", "taa", "--quiet", "-o", seq, *inputs)
    assert max_diff(lib, seq, out, range(1, 9)) == 0.0
    # A sidecar changed since (frame 6's): its output and the later ones again.
    sidecar = folder / "frame_0006.json"
    st = os.stat(sidecar)
    os.utime(sidecar, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    before = mtimes(out)
    p = crisp("filter", "--method", "taa", "--resume", "-o", out, *inputs)
    assert "frame_0006' was made from another version of" in p.stderr, p.stderr
    assert rewritten(before, out) == [6, 7, 8]
    p = crisp("filter", "--method", "taa", "--resume", "-o", out, *inputs)
    assert "nothing to do" in p.stdout, p.stderr
    # A farm chunk 5-8 whose pre-roll (1-4) holds a changed frame 2: remade; chunk 1-4 from 2 on.
    chunks = tmp_path / "chunks"
    filter_chunks(inputs, "taa", chunks, [(1, 4), (5, 8)], 4)
    st = os.stat(folder / frame(2))
    os.utime(folder / frame(2), ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    before = mtimes(chunks)
    p = crisp("filter", "--method", "taa", "--frames", "5-8", "--preroll", "4", "--resume", "-o", chunks, *inputs)
    assert "frame_0005' was made after other inputs before it" in p.stderr, p.stderr
    filter_chunks(inputs, "taa", chunks, [(1, 4)], 4, "--resume")
    assert rewritten(before, chunks) == [2, 3, 4, 5, 6, 7, 8]
    # A spatial method: a changed frame 3 leaves the outputs of 4-8 valid, and its resume makes
    # only the frames that need it (3 and 6 here), keeping the others (progress says "kept").
    spatial = tmp_path / "fxaa"
    crisp("filter", "--method", "fxaa", "--quiet", "-o", spatial, *inputs)
    st = os.stat(folder / frame(3))
    os.utime(folder / frame(3), ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    p = crisp("filter", "--method", "fxaa", "--frames", "4-8", "--resume", "-o", spatial, *inputs)
    assert "nothing to do" in p.stdout, p.stderr
    before = mtimes(spatial)
    os.remove(spatial / frame(6))
    p = crisp("filter", "--method", "fxaa", "--frames", "3-8", "--resume", "-o", spatial, *inputs)
    assert "frame_0003' was made from another version of" in p.stderr, p.stderr
    assert "frame_0006' is missing" in p.stderr and "frame_0005 (kept)" in p.stderr, p.stderr
    assert rewritten(before, spatial) == [3, 6]
    fresh = tmp_path / "fxaa_fresh"
    crisp("filter", "--method", "fxaa", "--quiet", "-o", fresh, *inputs)
    assert max_diff(lib, fresh, spatial, range(1, 9)) == 0.0
    # An output another build of crisp made (its stamp says which): made again.
    stamp = spatial / ".crisp" / frame(6, ".json")
    record = json.loads(stamp.read_text())
    record["build"] = "crisp 0.0.1 executable fnv1a64:0000000000000000"
    stamp.write_text(json.dumps(record) + "\n")
    p = crisp("filter", "--method", "fxaa", "--frames", "6-8", "--resume", "-o", spatial, *inputs)
    assert "frame_0006' was made by another build of crisp (crisp 0.0.1" in p.stderr, p.stderr
    # An output EXR replaced by another program, or a PNG this command did not write: made again.
    shutil.copy2(folder / frame(4), spatial / frame(4))
    p = crisp("filter", "--method", "fxaa", "--resume", "-o", spatial, *inputs)
    assert "frame_0004' was replaced since this command wrote it" in p.stderr, p.stderr
    crisp("filter", "--method", "taa", "--png", "--quiet", "-o", spatial, *inputs)
    for f in range(1, 9):  # touched since (say the folder was copied): no longer known as taa's own
        st = os.stat(spatial / frame(f, ".png"))
        os.utime(spatial / frame(f, ".png"), ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    p = crisp("filter", "--method", "fxaa", "--quiet", "-o", spatial, *inputs)
    assert "kept '%s'" % (spatial / frame(1, ".png")) in p.stderr, p.stderr  # taa's PNGs, kept and named
    p = crisp("filter", "--method", "fxaa", "--png", "--resume", "-o", spatial, *inputs)
    assert "frame_0001' has a PNG this command did not write" in p.stderr, p.stderr
    # A sidecar gone: the motion of every frame is no longer rebuilt from the sidecars, so every
    # output of a method that reads motion is made again.
    os.remove(folder / "frame_0008.json")
    p = crisp("filter", "--method", "taa", "--resume", "-o", out, *inputs)
    assert "frame_0001' was made with motion rebuilt from the sidecars" in p.stderr, p.stderr


def test_filter_resume_keeps_outputs_after_a_gap_when_an_earlier_input_changed(shot, lib, tmp_path):
    """A temporal method's history starts over at a gap in the frame numbers (or a cut), so its
    outputs after the gap do not depend on the inputs before it: a stamp's history digest restarts
    there, and a chunk after the gap whose pre-roll reaches a changed earlier input stays complete."""
    source, _ = shot
    folder = tmp_path / "input"
    shutil.copytree(source / "input", folder)
    frames = (1, 2, 3, 5, 6, 7, 8)
    inputs = [str(folder / frame(f)) for f in frames]  # frame 4 left out: a gap
    out = tmp_path / "out"
    p = crisp("filter", "--method", "taa", "-o", out, *inputs)
    assert "history starts over (frame 5 after frame 3)" in p.stderr, p.stderr
    p = crisp("filter", "--method", "taa", "--resume", "-o", out, *inputs)
    assert "nothing to do" in p.stdout, p.stderr  # the digests written restart where the plan does
    st = os.stat(folder / frame(2))
    os.utime(folder / frame(2), ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    before = mtimes(out, frames)
    # The chunk of positions 4-7 (frames 5-8), its pre-roll reaching frame 2: still complete.
    p = crisp("filter", "--method", "taa", "--frames", "4-7", "--preroll", "3", "--resume", "-o", out, *inputs)
    assert "nothing to do" in p.stdout, p.stderr
    # The chunk before the gap: frames 2 and 3 again, the outputs after the gap kept.
    p = crisp("filter", "--method", "taa", "--frames", "1-3", "--resume", "-o", out, *inputs)
    assert "frame_0002' was made from another version of" in p.stderr, p.stderr
    assert rewritten(before, out) == [2, 3]
    fresh = tmp_path / "fresh"
    crisp("filter", "--method", "taa", "--quiet", "-o", fresh, *inputs)
    assert max_diff(lib, fresh, out, frames) == 0.0
    # A chunk starting at the gap without pre-roll rebuilds its first frame's motion from the input
    # before it (frame 3), a run across the gap gives that frame zero motion: phlm's later frames
    # differ, so the chunk's outputs are not taken for the run's (their digests differ).
    alone, across = tmp_path / "alone", tmp_path / "across"
    crisp("filter", "--method", "phlm", "--frames", "4-7", "--quiet", "-o", alone, *inputs)
    crisp("filter", "--method", "phlm", "--frames", "4-7", "--preroll", "3", "--quiet", "-o", across, *inputs)
    assert max_diff(lib, alone, across, (6, 7, 8)) > 0.0  # the case is real
    p = crisp("filter", "--method", "phlm", "--frames", "4-7", "--preroll", "3", "--resume", "-o", alone, *inputs)
    assert "frame_0005' was made after other inputs before it" in p.stderr, p.stderr
    assert max_diff(lib, alone, across, (5, 6, 7, 8)) == 0.0


def test_filter_quiet_still_says_where_the_history_starts_over(shot, tmp_path):
    """--quiet hides progress and notes, not warnings: the line saying a temporal method's history
    starts over (a gap, a cut), which docs/farm.md tells farm users to look for, was hidden by it."""
    source, _ = shot
    inputs = [str(source / "input" / frame(f)) for f in (1, 2, 3, 5, 6)]  # frame 4 left out: a gap
    p = crisp("filter", "--method", "taa", "--quiet", "-o", tmp_path / "out", *inputs)
    assert "history starts over (frame 5 after frame 3)" in p.stderr, p.stderr
    assert p.stderr.count("\n") == 1 and p.stdout == "", p.stderr + p.stdout  # and no progress


def test_filter_chunk_errors(shot, tmp_path):
    _, inputs = shot
    for frames, message in (("7-9", "reaches past the last input (8 given"), ("0-3", "--frames expects A-B"),
                            ("5-2", "--frames expects A-B"), ("x", "--frames expects A-B")):
        p = crisp("filter", "--method", "taa", "--frames", frames, "-o", tmp_path, *inputs, ok=False)
        assert p.returncode == 2 and message in p.stderr, p.stderr
    p = crisp("filter", "--method", "taa", "--preroll", "-1", "-o", tmp_path, *inputs, ok=False)
    assert p.returncode == 2 and "--preroll" in p.stderr
    assert not os.listdir(tmp_path)


def test_render_chunks_equal_sequential_and_resume(shot, lib, tmp_path):
    seq, _ = shot
    out = tmp_path / "chunked"
    chunk_args = ("--shot", "1-8", "--preroll", "6")
    # The second chunk alone first: its pre-roll (6, clipped to frames 1-4) goes to a temporary folder.
    render(out, (5, 8), "taa-improved", *chunk_args)
    alone = json.loads((out / "run_0005-0008.json").read_text())
    assert sorted(os.listdir(out / "filtered")) == [".crisp"] + [frame(f, e) for f in range(5, 9) for e in (".exr", ".png")]
    # The records of the PNGs written (so a later run without PNGs knows them from the user's).
    assert sorted(os.listdir(out / "filtered" / ".crisp")) == [frame(f, ".png.json") for f in range(5, 9)]
    assert sorted(os.listdir(out / "input")) == [frame(f, e) for f in range(5, 9) for e in (".exr", ".json")]
    assert not os.path.exists(out / "run.json") and os.path.isfile(out / "run_0005-0008.json")

    # Then, at the same time into the same folder as on a farm: the first chunk, and the second chunk
    # resumed after losing frame 7's filtered EXR (5 and 6 stay; its pre-roll 1-6 is read from input/
    # where the first chunk or the earlier run already wrote it, else rendered again).
    os.remove(out / "filtered" / frame(7))
    kept = os.stat(out / "filtered" / frame(6)).st_mtime_ns
    procs = [subprocess.Popen([CRISP, "render", "--scene", "spinning_cube", "--resolution", SIZE, "--frames", frames,
                               "--method", "taa-improved", *chunk_args, *extra, "--quiet", "-o", str(out)],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
             for frames, extra in (("1-4", ()), ("5-8", ("--resume",)))]
    for p in procs:
        _, err = p.communicate(timeout=300)
        assert p.returncode == 0, err[-3000:]
    assert sorted(os.listdir(out)) == ["filtered", "input", "run_0001-0004.json", "run_0005-0008.json"]
    assert sorted(os.listdir(out / "input")) == [frame(f, e) for f in range(1, 9) for e in (".exr", ".json")]
    assert max_diff(lib, seq / "filtered", out / "filtered", range(1, 9)) == 0.0
    assert max_diff(lib, seq / "input", out / "input", range(1, 9)) == 0.0
    before = {e["frame"]: e for e in alone["frames"]}
    result = json.loads((out / "run_0005-0008.json").read_text())
    assert result["chunk"]["resumed_at"] == 7 and result["chunk"]["preroll_frames"] == [1, 6]
    assert {5, 6} <= set(result["chunk"]["preroll_reused"])
    # The resume's record keeps the frames made before it (5, 6), beside those it made (7, 8).
    assert [e["frame"] for e in result["frames"]] == [5, 6, 7, 8]
    assert [result["frames"][i] for i in (0, 1)] == [before[5], before[6]]
    assert os.stat(out / "filtered" / frame(6)).st_mtime_ns == kept
    first = json.loads((out / "run_0001-0004.json").read_text())
    assert first["chunk"]["preroll_frames"] is None and [e["frame"] for e in first["frames"]] == [1, 2, 3, 4]


@pytest.fixture(scope="module")
def transparent_shot(tmp_path_factory):
    """spinning_cube with Film > Transparent, saved as a .blend, rendered by `crisp render --method
    taa-improved` (frames 1-8): a cube over an empty film, its outline in alpha."""
    d = tmp_path_factory.mktemp("transparent")
    blend = str(d / "spinning_cube_transparent.blend")
    code = ("import sys; sys.path.insert(0, %r); import bpy, spinning_cube; s = spinning_cube.build(); "
            "s.render.film_transparent = True; bpy.ops.wm.save_as_mainfile(filepath=%r)"
            % (os.path.join(SOURCE, "test_scenes"), blend))
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr", code],
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=300)
    assert p.returncode == 0 and os.path.isfile(blend), p.stderr[-3000:]
    out = d / "sequential"
    crisp("render", "--scene", blend, "--resolution", SIZE, "--frames", "1-8", "--method", "taa-improved",
          "--quiet", "-o", out)
    return blend, out, [str(out / "input" / frame(f)) for f in range(1, 9)]


def test_a_transparent_films_chunks_equal_sequential(transparent_shot, lib, tmp_path):
    """The temporal methods filter a transparent film's alpha (native/filters/temporal_alpha.h): their
    chunks with a pre-roll back to frame 1, in `crisp filter` and `crisp render`, equal the sequential
    run in colour and alpha bit for bit, as the add-on's filter path does."""
    blend, seq, inputs = transparent_shot
    frames = range(1, 9)
    alphas = [lib.color(p)[..., 3] for p in inputs]
    assert all(np.all((a == 0.0) | (a == 1.0)) for a in alphas) and min(a.min() for a in alphas) == 0.0
    for method in TEMPORAL:
        whole, chunked = tmp_path / method / "seq", tmp_path / method / "chunks"
        crisp("filter", "--method", method, "--quiet", "-o", whole, *inputs)
        filter_chunks(inputs, method, chunked, [(1, 3), (4, 6), (7, 8)], 6)
        assert max_diff(lib, whole, chunked, frames) == 0.0, method
        last = lib.color(str(whole / frame(8)))[..., 3]
        assert np.any((last > 0.05) & (last < 0.95)), "%s anti-aliases the alpha" % method
    # The add-on's path (crisp render's filtered/) is the CLI's, and so is a render chunk's.
    assert max_diff(lib, seq / "filtered", tmp_path / "taa-improved" / "seq", frames) == 0.0
    out = tmp_path / "render_chunk"
    crisp("render", "--scene", blend, "--resolution", SIZE, "--frames", "5-8", "--shot", "1-8", "--preroll", "4",
          "--method", "taa-improved", "--quiet", "-o", out)
    assert max_diff(lib, seq / "filtered", out / "filtered", range(5, 9)) == 0.0


# Compiles a job of the Flamenco job type flamenco/crisp-render.js under Node.js, with the stub of
# Flamenco's job-compiler API that tests/flamenco/test_job_type.mjs uses: prints its tasks as JSON.
_COMPILE_JOB = r"""
const fs = require("fs"), vm = require("vm");
const author = {
  Task(name, type) { return { name, type, commands: [], addCommand(c) { this.commands.push(c); }, addDependency() {} }; },
  Command(name, parameters) { return { name, parameters }; },
};
const context = vm.createContext({ author, print: () => {} });
vm.runInContext(fs.readFileSync(process.argv[1], "utf8") + "\n;globalThis.__jobType = JOB_TYPE;", context);
const settings = {};
for (const s of context.__jobType.settings) if (s.default !== undefined) settings[s.key] = s.default;
const job = { settings: Object.assign(settings, JSON.parse(process.argv[2])), tasks: [], addTask(t) { this.tasks.push(t); } };
context.compileJob(job);
console.log(JSON.stringify(job.tasks.map((t) => ({ name: t.name, type: t.type, commands: t.commands }))));
"""


@pytest.mark.skipif(shutil.which("node") is None, reason="node not installed (the Flamenco job type is JavaScript)")
def test_the_flamenco_job_types_chunks_equal_sequential(shot, lib, tmp_path):
    """docs/farm.md: the commands the job type makes for frames 1-8, chunk size 3, pre-roll 8,
    taa-improved, run by the real CLI in reverse order into one folder (as workers may take them),
    give filtered frames bit-identical to one sequential `crisp render --frames 1-8`."""
    seq, _ = shot
    out = tmp_path / "farm"
    settings = {"blendfile": "spinning_cube", "frames": "1-8", "chunk_size": 3, "preroll": 8,
                "method": "taa-improved", "output_dir": str(out), "resolution": SIZE}
    p = subprocess.run(["node", "-e", _COMPILE_JOB, os.path.join(SOURCE, "flamenco", "crisp-render.js"),
                        json.dumps(settings)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    tasks = json.loads(p.stdout)
    assert [t["name"] for t in tasks] == ["crisp-1-3", "crisp-4-6", "crisp-7-8"]
    for task in reversed(tasks):
        (command,) = task["commands"]
        assert command["name"] == "exec" and command["parameters"]["exe"] == "crisp"
        # What the Manager hands a worker: its {blender} variable expanded (here: blender on PATH).
        args = ["blender" if a == "{blender}" else a for a in command["parameters"]["args"]]
        crisp(*args, "--quiet")
    assert sorted(os.listdir(out)) == ["filtered", "input", "run_0001-0003.json", "run_0004-0006.json",
                                       "run_0007-0008.json"]
    assert [json.loads((out / name).read_text())["chunk"]["preroll_frames"]
            for name in ("run_0001-0003.json", "run_0004-0006.json", "run_0007-0008.json")] == [None, [1, 3], [1, 6]]
    assert max_diff(lib, seq / "filtered", out / "filtered", range(1, 9)) == 0.0


def test_render_reuses_only_what_the_same_settings_made(shot, lib, tmp_path):
    """A resume keeps the frames that these settings made (each input sidecar's made_with): with
    another method or parameters it makes them again; a resume with nothing to do keeps the folder's
    record; a chunk's pre-roll does not read input frames rendered from another version of the scene's
    file."""
    seq, _ = shot
    out = tmp_path / "copy"
    shutil.copytree(seq, out)
    mtime = os.stat(out / "filtered" / frame(3)).st_mtime_ns
    render(out, SHOT, "taa-improved", "--resume")  # nothing to do
    assert [e["frame"] for e in json.loads((out / "run.json").read_text())["frames"]] == list(range(1, 9))
    assert os.stat(out / "filtered" / frame(3)).st_mtime_ns == mtime
    # A run stopped after writing frame 6's input, before its outputs (those found are an earlier
    # run's, older than the input): the resume makes 6 on.
    st = os.stat(out / "input" / frame(6, ".json"))
    os.utime(out / "input" / frame(6, ".json"), ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    kept, stale = (os.stat(out / "filtered" / frame(f)).st_mtime_ns for f in (5, 6))
    p = crisp("render", "--scene", "spinning_cube", "--resolution", SIZE, "--frames", "%d-%d" % SHOT,
              "--method", "taa-improved", "-o", out, "--resume")
    assert "frame 6: frame_0006.exr, frame_0006.png older than its input" in p.stderr + p.stdout, p.stderr[-2000:]
    assert os.stat(out / "filtered" / frame(6)).st_mtime_ns != stale
    assert os.stat(out / "filtered" / frame(5)).st_mtime_ns == kept
    render(out, SHOT, "taa-improved", "--resume", "--set", "feedbackMin=0.5")
    assert os.stat(out / "filtered" / frame(3)).st_mtime_ns != mtime
    variant = tmp_path / "variant"
    render(variant, SHOT, "taa-improved", "--set", "feedbackMin=0.5")
    assert max_diff(lib, variant / "filtered", out / "filtered", range(1, 9)) == 0.0
    side = json.loads((out / "input" / frame(1, ".json")).read_text())
    assert side["made_with"]["params"] == {"feedbackMin": "0.5"} and side["made_with"]["method"] == "taa-improved"
    # The same value spelt otherwise (a farm job's text, the panel's float32) is the same setting: kept.
    mtime = os.stat(out / "filtered" / frame(3)).st_mtime_ns
    render(out, SHOT, "taa-improved", "--resume", "--set", "feedbackMin=0.50")
    assert os.stat(out / "filtered" / frame(3)).st_mtime_ns == mtime

    # The same scene name from an edited script (CRISP_ADDON_DIR: another tree's add-on and scenes).
    env = dict(os.environ, CRISP_ADDON_DIR=addon_with_spinning_cube_ending(tmp_path, "# edited"))
    tree = tmp_path / "tree"
    p = subprocess.run([CRISP, "render", "--scene", "spinning_cube", "--resolution", SIZE, "--frames", "5-8",
                        "--shot", "1-8", "--preroll", "4", "--method", "taa-improved", "--quiet", "-o", str(out)],
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, timeout=300)
    assert p.returncode == 0, p.stderr[-3000:]
    chunk = json.loads((out / "run_0005-0008.json").read_text())["chunk"]
    assert chunk["preroll_frames"] == [1, 4] and chunk["preroll_reused"] == []
    # Nor from an edit of the scenes' shared test_scenes/common.py (the scene's own script as before).
    shutil.copy(os.path.join(SOURCE, "test_scenes", "spinning_cube.py"), tree / "test_scenes" / "spinning_cube.py")
    with open(tree / "test_scenes" / "common.py", "a") as f:
        f.write("\n# edited\n")
    # (Frames 3-4 in input/ are the first run's: pre-roll never writes there.)
    p = subprocess.run([CRISP, "render", "--scene", "spinning_cube", "--resolution", SIZE, "--frames", "5-6",
                        "--shot", "1-8", "--preroll", "2", "--method", "taa-improved", "--quiet", "-o", str(out)],
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, timeout=300)
    assert p.returncode == 0, p.stderr[-3000:]
    chunk = json.loads((out / "run_0005-0006.json").read_text())["chunk"]
    assert chunk["preroll_frames"] == [3, 4] and chunk["preroll_reused"] == [], chunk


def test_render_chunk_without_shot_and_resume_of_lost_files(tmp_path):
    """--preroll without --shot takes the scene's range as the shot (the chunk's record is
    run_AAAA-BBBB.json, so chunks never overwrite each other's); a spatial method renders no pre-roll;
    a resume makes again a frame whose input EXR or reference was lost, though its other files stay."""
    out = tmp_path / "chunk"
    render(out, (5, 6), "taa", "--preroll", "2")
    assert not os.path.exists(out / "run.json")
    chunk = json.loads((out / "run_0005-0006.json").read_text())["chunk"]
    assert chunk["preroll_frames"] == [3, 4] and chunk["preroll_reused"] == [], chunk
    # Input frames at another size are not read as pre-roll (those of the same size are).
    render(out, (3, 4), "taa")
    render(out, (5, 6), "taa", "--preroll", "2")
    assert json.loads((out / "run_0005-0006.json").read_text())["chunk"]["preroll_reused"] == [3, 4]
    crisp("render", "--scene", "spinning_cube", "--resolution", "48x27", "--frames", "5-6", "--preroll", "2",
          "--method", "taa", "--quiet", "-o", out)
    chunk = json.loads((out / "run_0005-0006.json").read_text())["chunk"]
    assert chunk["preroll_frames"] == [3, 4] and chunk["preroll_reused"] == [], chunk
    spatial = tmp_path / "spatial"
    render(spatial, (5, 6), "fxaa", "--preroll", "2")
    assert json.loads((spatial / "run_0005-0006.json").read_text())["chunk"]["preroll_frames"] is None
    whole = tmp_path / "whole"
    render(whole, (1, 2), "fxaa", "--reference-samples", "2")
    os.remove(whole / "input" / frame(1))  # its sidecar stays
    kept = os.stat(whole / "filtered" / frame(1)).st_mtime_ns
    render(whole, (1, 2), "fxaa", "--reference-samples", "2", "--resume")
    assert (whole / "input" / frame(1)).is_file()
    assert os.stat(whole / "filtered" / frame(1)).st_mtime_ns != kept, "frame 1 made again from its new input"
    os.remove(whole / "reference" / frame(2))  # the last frame's reference alone
    kept = os.stat(whole / "filtered" / frame(1)).st_mtime_ns
    render(whole, (1, 2), "fxaa", "--reference-samples", "2", "--resume")
    assert (whole / "reference" / frame(2)).is_file()
    assert os.stat(whole / "filtered" / frame(1)).st_mtime_ns == kept, "frame 1 was complete"
    record = json.loads((whole / "run.json").read_text())
    assert record["status"] == "complete", record["status"]


def _processes_naming(text):
    """Pids of the running processes whose command line holds text."""
    pids = []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            with open("/proc/%s/cmdline" % pid, "rb") as f:
                if text.encode() in f.read():
                    pids.append(int(pid))
        except OSError:
            pass
    return pids


@pytest.mark.parametrize("how", ["SIGTERM", "Ctrl-C", "SIGKILL", "SIGTERM in a handler"])
def test_a_stopped_render_stops_blender_and_says_so(tmp_path, how):
    """A farm cancelling a task signals crisp (SIGTERM; a lost task's process may get SIGKILL), a
    terminal's Ctrl-C signals crisp and Blender: Blender stops with it after the frame it is on, rather
    than going on alone into the shared folder (and ending "complete"); the chunk's record says why it
    stopped, and no temporary file or pre-roll folder is left. Also when the stop lands in Python that
    Blender runs and reports itself (a scene's frame change handler), which swallows the exception."""
    import signal
    out, tmp = tmp_path / "out", tmp_path / "tmp"
    tmp.mkdir()
    env = dict(os.environ, TMPDIR=str(tmp))
    if how == "SIGTERM in a handler":  # the bundled scene with a slow handler
        env["CRISP_ADDON_DIR"] = addon_with_spinning_cube_ending(
            tmp_path, "import bpy\nimport time\nbpy.app.handlers.frame_change_pre.append(lambda *_: time.sleep(0.2))\n")
    sig = {"SIGTERM": signal.SIGTERM, "Ctrl-C": signal.SIGINT, "SIGKILL": signal.SIGKILL,
           "SIGTERM in a handler": signal.SIGTERM}[how]
    last = 60 if how == "SIGTERM in a handler" else 900  # a shot long enough to stop part-way
    p = subprocess.Popen([CRISP, "render", "--scene", "spinning_cube", "--resolution", SIZE, "--frames", "3-%d" % last,
                          "--shot", "1-%d" % last, "--preroll", "2", "--method", "taa", "-o", str(out)],  # as the job type runs it
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env,
                         start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    record = out / ("run_0003-%04d.json" % last)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and p.poll() is None:
            try:
                if json.loads(record.read_text())["frames"]:
                    break
            except (OSError, ValueError, KeyError):
                pass
            time.sleep(0.05)
        assert p.poll() is None, "the run ended before it was stopped"
        if how == "Ctrl-C":
            os.killpg(p.pid, sig)  # the terminal signals its foreground process group
        else:
            p.send_signal(sig)
        p.wait(timeout=60)
        assert p.returncode == -sig
        time.sleep(1)
        assert _processes_naming(str(out)) == [], "Blender goes on after crisp stopped"
    finally:
        for pid in _processes_naming(str(out)):
            os.kill(pid, signal.SIGKILL)
        if p.poll() is None:
            p.kill()
    status = json.loads(record.read_text())["status"]
    assert status == {"Ctrl-C": "failed: KeyboardInterrupt"}.get(how, "failed: stopped by SIGTERM")
    made = len(json.loads(record.read_text())["frames"])
    assert 0 < made < last - 2
    left = [os.path.join(d, n) for d in ("input", "filtered", "filtered/.crisp") for n in os.listdir(out / d)
            if n != ".crisp" and (n.startswith(".") or ".tmp" in n)]
    assert left == [] and [n for n in os.listdir(tmp) if n.startswith("crisp")] == []


def test_a_render_stopped_while_its_scene_is_made_says_so(tmp_path):
    """A stop signal that comes while batch.py builds the scene, before the run: a clear error, not a
    Python traceback."""
    import signal
    addon = addon_with_spinning_cube_ending(
        tmp_path, "import os\nimport time\nopen(os.environ['CRISP_TEST_BUILDING'], 'w').close()\ntime.sleep(30)\n")
    building = tmp_path / "building"
    p = subprocess.Popen([CRISP, "render", "--scene", "spinning_cube", "--resolution", SIZE, "--frames", "1-2",
                          "--method", "taa", "-o", str(tmp_path / "out")], stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, text=True,
                         env=dict(os.environ, CRISP_ADDON_DIR=addon, CRISP_TEST_BUILDING=str(building)))
    try:
        deadline = time.monotonic() + 120
        while not building.exists() and time.monotonic() < deadline and p.poll() is None:
            time.sleep(0.05)
        assert building.exists(), "the scene script did not run"
        p.send_signal(signal.SIGTERM)
        out, _ = p.communicate(timeout=60)
    finally:
        if p.poll() is None:
            p.kill()
    assert p.returncode == -signal.SIGTERM
    assert "crisp: error: stopped by SIGTERM" in out and "Traceback" not in out, out[-2000:]


def test_a_chunk_removes_preroll_folders_of_killed_runs(tmp_path):
    """A pre-roll folder holds a chunk's worth of full-size EXRs in the worker's temporary folder; a run
    killed outright (kill -9, a crash) cannot delete its own, so the next chunk with a pre-roll on the
    host removes those of processes that no longer run, once a minute old, and leaves the others."""
    import socket
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    host = "".join(c if c.isascii() and (c.isalnum() or c in "_.-") else "_" for c in socket.gethostname())[:64]
    gone = subprocess.Popen(["true"])
    gone.wait()
    old = time.time() - 120
    folders = {"stale": "crisp-preroll-%d-%s-abc" % (gone.pid, host),  # killed a while ago
               "young": "crisp-preroll-%d-%s-def" % (gone.pid, host),  # just killed, or just made
               "running": "crisp-preroll-%d-%s-ghi" % (os.getpid(), host),
               "other host": "crisp-preroll-%d-%s-jkl" % (gone.pid, host + "x"),
               "not ours": "crisp-preroll-xyz"}
    for what, name in folders.items():
        (tmp / name).mkdir()
        (tmp / name / frame(1)).write_text("pre-roll")
        if what != "young":
            os.utime(tmp / name, (old, old))
    p = subprocess.run([CRISP, "render", "--scene", "spinning_cube", "--resolution", SIZE, "--frames", "3-3",
                        "--preroll", "1", "--method", "taa", "-o", str(tmp_path / "out")],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, env=dict(os.environ, TMPDIR=str(tmp)),
                       timeout=300)
    assert p.returncode == 0, p.stdout[-3000:]
    assert sorted(os.listdir(tmp)) == sorted(n for w, n in folders.items() if w != "stale")
    assert "removed %s" % (tmp / folders["stale"]) in p.stdout


def test_one_chunk_run_twice_at_once_and_temporaries_of_killed_runs(shot, lib, tmp_path):
    """A task that Flamenco gave to a second worker while the first still runs it: two runs of one chunk
    into one folder at once write the same files, each through a temporary name of its own (host,
    process, call), so both succeed and the frames are the sequential run's; before, they shared
    ".frame_N.exr.tmp" and one failed ("Blender wrote no file", "No such file or directory") at
    whichever file the other renamed away first. A temporary file that a run killed mid-write left
    (its process gone, a minute old) is removed by the next run into that folder."""
    import socket
    seq, _ = shot
    out = tmp_path / "twice"
    for _ in range(2):  # the race is not hit every time at this size
        shutil.rmtree(out, ignore_errors=True)
        procs = [subprocess.Popen([CRISP, "render", "--scene", "spinning_cube", "--resolution", "320x180",
                                   "--frames", "1-8", "--shot", "1-8", "--preroll", "8", "--method", "taa-improved",
                                   "--resume", "--quiet", "-o", str(out)],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True) for _ in range(2)]
        for p in procs:
            _, err = p.communicate(timeout=300)
            assert p.returncode == 0, err[-3000:]
    assert [n for d in ("", "input", "filtered", "filtered/.crisp") for n in os.listdir(out / d) if ".tmp" in n] == []
    once = tmp_path / "once"
    crisp("render", "--scene", "spinning_cube", "--resolution", "320x180", "--frames", "1-8", "--method",
          "taa-improved", "--quiet", "-o", once)
    assert max_diff(lib, once / "filtered", out / "filtered", range(1, 9)) == 0.0

    host = "".join(c if c.isascii() and (c.isalnum() or c in "_.-") else "_" for c in socket.gethostname())[:64]
    gone = subprocess.Popen(["true"])
    gone.wait()
    old = time.time() - 120
    out = tmp_path / "killed"
    render(out, SHOT)
    left = {"input": ".frame_0004.tmp-%s-%d-0.exr" % (host, gone.pid),
            "filtered": ".frame_0004.tmp-%s-%d-1.png" % (host, gone.pid),
            "filtered/.crisp": ".frame_0004.png.tmp-%s-%d-2.json" % (host, gone.pid),
            "": ".run.tmp-%s-%d-3.json" % (host, gone.pid)}
    young = out / "input" / (".frame_0005.tmp-%s-%d-4.exr" % (host, gone.pid))  # a minute not yet past
    for folder, name in left.items():
        (out / folder / name).write_text("half")
        os.utime(out / folder / name, (old, old))
    young.write_text("half")
    render(out, SHOT, "taa-improved", "--resume")
    assert [name for folder, name in left.items() if (out / folder / name).exists()] == []
    assert young.exists()
    assert max_diff(lib, seq / "filtered", out / "filtered", range(1, 9)) == 0.0


def test_a_spatial_render_resume_makes_only_the_frames_that_need_it(tmp_path):
    """docs/farm.md, Resume: the run writes from the first missing frame to the end of the chunk, a
    spatial method only the frames that need it. Without a history every frame stands alone, so
    `crisp render --resume` of fxaa makes the frames whose outputs are missing and keeps the complete
    ones after the first (before, it rendered and filtered every frame after it again)."""
    out = tmp_path / "spatial"
    render(out, (1, 8), "fxaa")
    os.remove(out / "filtered" / frame(3))
    os.remove(out / "filtered" / frame(6, ".png"))
    before = {f: os.stat(out / "filtered" / frame(f)).st_mtime_ns for f in (1, 2, 4, 5, 7, 8)}
    inputs = {f: os.stat(out / "input" / frame(f)).st_mtime_ns for f in (4, 5, 7, 8)}
    p = render(out, (1, 8), "fxaa", "--resume")
    assert {f: os.stat(out / "filtered" / frame(f)).st_mtime_ns for f in before} == before
    assert {f: os.stat(out / "input" / frame(f)).st_mtime_ns for f in inputs} == inputs
    assert all((out / "filtered" / frame(f, e)).is_file() for f in (3, 6) for e in (".exr", ".png"))
    record = json.loads((out / "run.json").read_text())
    assert record["status"] == "complete" and record["chunk"]["resumed_at"] == 3
    assert [e["frame"] for e in record["frames"]] == list(range(1, 9))
    fresh = tmp_path / "fresh"
    render(fresh, (1, 8), "fxaa")
    assert max_diff(Lib(), fresh / "filtered", out / "filtered", range(1, 9)) == 0.0


def test_a_resume_remakes_the_frames_another_build_filtered(tmp_path):
    """A frame's made_with records which libcrisp file filtered it, so a resume with another build
    (an upgrade in the middle of a shot) makes the frames again rather than keeping another build's
    outputs beside this one's; the same build keeps them."""
    out = tmp_path / "out"
    render(out, (1, 2), "fxaa")
    other = tmp_path / "other"
    (other / "bin").mkdir(parents=True)
    (other / "lib").mkdir()
    shutil.copy2(CRISP, other / "bin" / "crisp")
    (other / "lib" / "libcrisp.so").write_bytes(open(LIBRARY, "rb").read() + b"\0")  # loads as before
    env = dict(os.environ, CRISP_ADDON_DIR=os.path.join(SOURCE, "addon"))

    def resume(crisp_cli):
        before = mtimes(out / "filtered", (1, 2))
        p = subprocess.run([str(crisp_cli), "render", "--scene", "spinning_cube", "--resolution", SIZE,
                            "--frames", "1-2", "--method", "fxaa", "--resume", "-o", str(out)],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300, env=env)
        assert p.returncode == 0, p.stdout[-3000:]
        return p.stdout, rewritten(before, out / "filtered")

    log, remade = resume(other / "bin" / "crisp")
    assert remade == [1, 2], log[-3000:]
    assert "made with other settings (library" in log
    assert resume(other / "bin" / "crisp")[1] == []
    assert resume(CRISP)[1] == [1, 2]


def test_a_resume_makes_again_a_frame_that_lost_a_subsample(tmp_path):
    """rsaa's frames have eight geometry sub-samples beside the input; one lost (a partial copy between
    farm storages) makes its frame incomplete, so a resume renders it again, and only it."""
    out = tmp_path / "rsaa"
    render(out, (1, 2), "rsaa")
    os.remove(out / "input" / "frame_0002_sub3.exr")
    before = mtimes(out / "filtered", (1, 2))
    render(out, (1, 2), "rsaa", "--resume")
    assert rewritten(before, out / "filtered") == [2]
    assert (out / "input" / "frame_0002_sub3.exr").is_file()


def test_a_chunk_with_a_preroll_of_0_is_a_chunk(tmp_path):
    """--preroll 0 is given (a spatial method's chunks, as docs/farm.md has the job type pass it): without
    --shot the shot is the scene's range, as for any --preroll, so each chunk writes its own
    run_AAAA-BBBB.json and is planned over the shot; before, 0 counted as not given, and every such
    chunk wrote run.json over the one before."""
    out = tmp_path / "spatial"
    render(out, (5, 6), "fxaa", "--preroll", "0")
    render(out, (7, 8), "fxaa", "--preroll", "0")
    assert sorted(n for n in os.listdir(out) if n.endswith(".json")) == ["run_0005-0006.json", "run_0007-0008.json"]
    for name, frames in (("run_0005-0006.json", [5, 6]), ("run_0007-0008.json", [7, 8])):
        record = json.loads((out / name).read_text())
        assert record["chunk"]["shot"] == [1, 48] and [e["frame"] for e in record["frames"]] == frames


def test_a_plan_keeps_the_record_of_a_run(shot, tmp_path):
    """--plan writes its plan to the run's record only where no run has made one: the plan of a farm job,
    asked of its own folder, left a complete chunk's run_AAAA-BBBB.json "planned", without its frames,
    and a later --resume then listed stubs ({"frame": 4}) for them."""
    seq, _ = shot
    out = tmp_path / "job"
    shutil.copytree(seq, out)  # a sequential run's run.json, and a chunk's record beside it
    render(out, (4, 6), "taa-improved", "--shot", "1-8", "--preroll", "3")
    for args, name in ((("--frames", "4-6", "--shot", "1-8", "--preroll", "3"), "run_0004-0006.json"),
                       (("--frames", "1-8"), "run.json")):
        before = (out / name).read_text()
        p = crisp("render", "--scene", "spinning_cube", "--resolution", SIZE, "--method", "taa-improved",
                  "--plan", "-o", out, *args)
        assert "plan for taa-improved" in p.stdout and "kept %s" % (out / name) in p.stdout, p.stdout[-2000:]
        assert (out / name).read_text() == before
    record = json.loads((out / "run_0004-0006.json").read_text())
    assert record["status"] == "complete" and all("render_s" in e for e in record["frames"])
    fresh = tmp_path / "fresh"
    crisp("render", "--scene", "spinning_cube", "--resolution", SIZE, "--method", "taa", "--plan", "--quiet", "-o", fresh)
    assert json.loads((fresh / "run.json").read_text())["status"] == "planned"


def test_a_run_that_keeps_nothing_is_not_recorded_as_resumed(tmp_path):
    """The job type passes --resume to every task: a chunk's record says resumed_at only when the run kept
    frames made before it, so a TD can tell the tasks that were resumed from those that ran afresh."""
    out = tmp_path / "job"
    render(out, (5, 8), "taa", "--shot", "1-8", "--preroll", "2", "--resume")
    assert json.loads((out / "run_0005-0008.json").read_text())["chunk"]["resumed_at"] is None
    os.remove(out / "filtered" / frame(7))
    render(out, (5, 8), "taa", "--shot", "1-8", "--preroll", "2", "--resume")
    assert json.loads((out / "run_0005-0008.json").read_text())["chunk"]["resumed_at"] == 7


MAKE_EARLY_MOTION = """
import sys
sys.path[:0] = [%r]
import bpy, math
import spinning_cube
scene = spinning_cube.build()
cube = scene.objects["Cube"]
cube.animation_data_clear()
for f, angle in ((1, 0.0), (4, 30.0)):  # turns over frames 1-4, still from 4 on (constant extrapolation)
    cube.rotation_euler = (0.0, 0.0, math.radians(angle))
    cube.keyframe_insert("rotation_euler", frame=f)
bpy.ops.wm.save_as_mainfile(filepath=%r)
"""


def test_a_chunk_is_planned_over_its_shot(tmp_path):
    """A chunk reads the passes its shot needs, not only its own frames: frames 5-8 of a shot whose
    cube turns over frames 1-4 get motion, as the sequential run's frames do, so every chunk of a
    shot renders the same passes."""
    blend = tmp_path / "early_motion.blend"
    p = subprocess.run(["blender", "-b", "--factory-startup", "--python-exit-code", "1", "--python-expr",
                        MAKE_EARLY_MOTION % (os.path.join(SOURCE, "test_scenes"), str(blend))],
                       stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=300)
    assert p.returncode == 0 and blend.is_file(), p.stdout.decode()[-2000:]

    def plan(out, *extra):
        crisp("render", "--scene", blend, "--resolution", SIZE, "--frames", "5-8", "--method", "taa", "--plan",
              "--quiet", "-o", out, *extra)
        records = sorted(out.glob("run*.json"))
        assert len(records) == 1, records
        return json.loads(records[0].read_text())["plan"]["passes"]

    assert "motion" not in plan(tmp_path / "alone"), "frames 5-8 alone are still"
    assert "motion" in plan(tmp_path / "chunk", "--shot", "1-8")

    # A resume with another --shot, whose plan has other passes, makes again the frames made with the
    # old plan: the folder never mixes two plans under a record that names one.
    out = tmp_path / "reshot"
    crisp("render", "--scene", blend, "--resolution", SIZE, "--frames", "5-8", "--shot", "1-8", "--preroll", "4",
          "--method", "taa", "--quiet", "-o", out)
    os.remove(out / "filtered" / frame(7))
    p = crisp("render", "--scene", blend, "--resolution", SIZE, "--frames", "5-8", "--shot", "5-8", "--preroll", "4",
              "--method", "taa", "--resume", "-o", out)
    assert "frame 5 was made with other settings (passes" in p.stdout, p.stdout[-2000:]
    record = json.loads((out / "run_0005-0008.json").read_text())
    assert record["chunk"]["resumed_at"] is None and record["status"] == "complete"  # nothing kept
    assert {json.loads((out / "input" / frame(f, ".json")).read_text())["passes"] == record["plan"]["passes"]
            for f in range(5, 9)} == {True}


# ---- the pre-roll table (not a test) ---------------------------------------------------------------

MEASURE_SCENES = (("camera_dolly", 24, 21), ("spinning_cube", 24, 21), ("still_life", 48, 41))


def measure(out_dir, scenes=MEASURE_SCENES, prerolls=(0, 1, 2, 4, 8, 16, 32), chunk=4):
    """Per scene (name, frames rendered, chunk start) and method: the chunk's frames filtered with
    each pre-roll length against one sequential run from frame 1; each cell is max |difference|
    (linear RGB) / lowest PSNR in dB (display-encoded, as metrics.h) over the chunk's frames."""
    lib = Lib()
    print("| scene | method | chunk | " + " | ".join("pre-roll %d" % p for p in prerolls) + " |")
    print("|---|---|---|" + "---|" * len(prerolls))
    for scene, n, start in scenes:
        base = os.path.join(out_dir, scene)
        if not os.path.isfile(os.path.join(base, "input", frame(n, ".json"))):
            crisp("render", "--scene", scene, "--resolution", SIZE, "--frames", "1-%d" % n, "--method",
                  "taa-improved", "--quiet", "-o", base)
        inputs = [os.path.join(base, "input", frame(f)) for f in range(1, n + 1)]
        frames = range(start, start + chunk)
        for method in TEMPORAL:
            seq = os.path.join(base, method, "seq")
            crisp("filter", "--method", method, "--quiet", "-o", seq, *inputs)
            row = []
            for p in prerolls:
                if p >= start - 1:  # reaches frame 1: the sequential run itself
                    row.append("=")
                    continue
                d = os.path.join(base, method, "p%d" % p)
                filter_chunks(inputs, method, d, [(start, start + chunk - 1)], p)
                worst = min(psnr(lib.color(os.path.join(seq, frame(f))), lib.color(os.path.join(d, frame(f))))
                            for f in frames)
                row.append("%.3f / %.1f" % (max_diff(lib, seq, d, frames), worst))
            print("| %s | %s | %d-%d | %s |" % (scene, method, start, start + chunk - 1, " | ".join(row)), flush=True)


if __name__ == "__main__":
    # --measure [OUTDIR] [--scene NAME:FRAMES:CHUNK_START]... [--prerolls 0,1,2,...]
    argv, scenes, prerolls, out = sys.argv[1:], [], None, None
    while argv:
        a = argv.pop(0)
        if a == "--scene":
            name, n, start = argv.pop(0).split(":")
            scenes.append((name, int(n), int(start)))
        elif a == "--prerolls":
            prerolls = tuple(int(p) for p in argv.pop(0).split(","))
        elif a != "--measure":
            out = a
    if "--measure" in sys.argv:
        measure(out or tempfile.mkdtemp(prefix="crisp_preroll_"), tuple(scenes) or MEASURE_SCENES,
                prerolls or (0, 1, 2, 4, 8, 16, 32))


def test_cli_and_addon_take_each_frames_jitter_from_its_sidecar(shot, lib, tmp_path):
    """`crisp filter` and the add-on's FrameFilter both give temporal filters each frame's jitter from
    its sidecar: with the Blackman-Harris sample weighting (which reads the jitter) their outputs are
    bit-identical, and differ from the unweighted run (equal jitter everywhere would weight all
    frames alike, which is the unweighted running average)."""
    _, inputs = shot
    crisp("filter", "--method", "taa", "--set", "jitterWeighting=blackman-harris", "--quiet",
          "-o", tmp_path / "cli", *inputs)
    crisp("filter", "--method", "taa", "--quiet", "-o", tmp_path / "plain", *inputs)
    os.environ["CRISP_LIBRARY"] = LIBRARY
    # addon/crisp/native.py is pure ctypes; load it alone (the package's __init__ needs bpy).
    spec = importlib.util.spec_from_file_location("crisp_native", os.path.join(SOURCE, "addon", "crisp", "native.py"))
    native = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(native)
    ff = native.FrameFilter("taa", {"jitterWeighting": "blackman-harris"}, 0, ("color", "depth", "motion"))
    os.makedirs(tmp_path / "addon")
    for path in inputs:
        ff.run(path, [str(tmp_path / "addon" / os.path.basename(path))])
    frames = range(SHOT[0], SHOT[1] + 1)
    assert max_diff(lib, tmp_path / "cli", tmp_path / "addon", frames) == 0.0
    assert max_diff(lib, tmp_path / "cli", tmp_path / "plain", frames) > 0.0


def test_cli_takes_the_filter_size_from_the_sidecars_as_the_addon(shot, lib, tmp_path):
    """`crisp filter` gives a temporal filter each sidecar's Film > Filter Size (render_settings.
    filter_size), as the add-on takes the scene's (pipeline.with_scene_filter_size): the frames with
    their sidecars saying 0.75 filter as --set filterSize=0.75 on the originals (1.5), and not as the
    originals alone; a --set filterSize wins over the sidecars; a size the library refuses names
    the sidecar and the Film setting."""
    _, inputs = shot

    def folder(name, size):
        d = tmp_path / name
        d.mkdir()
        for f in range(1, 5):
            shutil.copy(inputs[f - 1], d / frame(f))
            with open(inputs[f - 1][:-len(".exr")] + ".json") as fh:
                data = json.load(fh)
            assert data["render_settings"]["filter_size"] == 1.5, data["render_settings"]
            data["render_settings"]["filter_size"] = size
            with open(d / frame(f, ".json"), "w") as fh:
                json.dump(data, fh)
        return [d / frame(f) for f in range(1, 5)]

    narrow = folder("narrow", 0.75)
    runs = {"narrow": (narrow, ()), "set": (inputs[:4], ("--set", "filterSize=0.75")), "plain": (inputs[:4], ()),
            "narrow_set": (narrow, ("--set", "filterSize=2")), "set2": (inputs[:4], ("--set", "filterSize=2"))}
    frames = range(1, 5)
    for method in TEMPORAL:
        for name, (files, extra) in runs.items():
            crisp("filter", "--method", method, "--quiet", *extra, "-o", tmp_path / method / name, *files)
        out = tmp_path / method
        assert max_diff(lib, out / "narrow", out / "set", frames) == 0.0, method
        assert max_diff(lib, out / "narrow", out / "plain", frames) > 0.0, method
        assert max_diff(lib, out / "narrow_set", out / "set2", frames) == 0.0, method
    wide = folder("wide", 6.0)
    p = crisp("filter", "--method", "taa", "-o", tmp_path / "wide_out", *wide, ok=False)
    assert p.returncode != 0 and "Film > Filter Size 6" in p.stderr and frame(1, ".json") in p.stderr, p.stderr


def test_a_frame_without_sidecar_is_not_given_the_previous_frames_jitter(shot, lib, tmp_path):
    """A frame with no sidecar (another renderer's) takes the jitter given with --set, or none: not
    the jitter of the frame before it, which the filter would otherwise keep. Frame 1 has no sidecar
    in every run, so no run rebuilds motion (that needs every frame's sidecar); frames 2 and 3 have
    theirs, and only frame 4's jitter differs between the runs."""
    _, inputs = shot

    def folder(name, last_jitter):
        d = tmp_path / name
        d.mkdir()
        for f in (1, 2, 3, 4):
            shutil.copy(inputs[f - 1], d / frame(f))
            side = inputs[f - 1][:-len(".exr")] + ".json"
            if f in (2, 3) or (f == 4 and last_jitter is not None):
                with open(side) as fh:
                    data = json.load(fh)
                if f == 4:
                    data["jitter"]["x"], data["jitter"]["y"] = last_jitter
                with open(d / frame(f, ".json"), "w") as fh:
                    json.dump(data, fh)
        return [d / frame(f) for f in (1, 2, 3, 4)]

    with open(inputs[2][:-len(".exr")] + ".json") as fh:
        second = json.load(fh)["jitter"]  # frame 3's, which the old code kept for frame 4
    runs = {"none": (folder("no_sidecar", None), ()), "zero": (folder("zero", (0.0, 0.0)), ()),
            "second": (folder("second", (second["x"], second["y"])), ()),
            "set": (folder("no_sidecar_set", None), ("--set", "jitterX=0.25")),
            "quarter": (folder("quarter", (0.25, 0.0)), ("--set", "jitterX=0.25"))}
    assert abs(second["x"]) + abs(second["y"]) > 0.05, second
    for name, (files, extra) in runs.items():
        crisp("filter", "--method", "taa", "--quiet", *extra, "-o", tmp_path / ("out_" + name), *files)

    def third(name):
        return lib.color(str(tmp_path / ("out_" + name) / frame(4)))
    assert np.array_equal(third("none"), third("zero"))
    assert not np.array_equal(third("none"), third("second")), "the jitter matters to this check"
    assert np.array_equal(third("set"), third("quarter"))


def test_what_the_sidecars_decide_is_said(shot, tmp_path):
    """A sequence where some inputs lack a sidecar loses their jitter and every frame's rebuilt
    motion: said before the run, naming the first missing sidecar; a jitter set with --set applies
    only to inputs without a sidecar: said; rsaa's camera, which every sidecar replaces, is refused."""
    _, inputs = shot
    d = tmp_path / "in"
    d.mkdir()
    for f in range(1, 5):
        shutil.copy(inputs[f - 1], d / frame(f))
        if f != 3:
            shutil.copy(inputs[f - 1][:-len(".exr")] + ".json", d / frame(f, ".json"))
    files = [d / frame(f) for f in range(1, 5)]
    p = crisp("filter", "--method", "taa", "--quiet", "-o", tmp_path / "a", *files)
    assert "1 of 4 inputs come without a sidecar (the first: '%s')" % (d / frame(3, ".json")) in p.stderr, p.stderr
    assert "motion is rebuilt from the sidecars for no input" in p.stderr, p.stderr
    p = crisp("filter", "--method", "fxaa", "--quiet", "-o", tmp_path / "b", *files)
    assert p.stderr == "", p.stderr  # fxaa reads neither jitter nor motion
    p = crisp("filter", "--method", "taa", "--set", "jitterX=0.25", "--set", " jitterX = 0.5", "--quiet",
              "-o", tmp_path / "c", *inputs[:3])
    assert p.stderr.count("--set jitterX applies only to inputs without a sidecar; 3 of 3 inputs have one") == 1, \
        p.stderr
    assert "without a sidecar (the first" not in p.stderr, p.stderr
    p = crisp("filter", "--method", "rsaa", "--set", "view01=0.5", "-o", tmp_path / "d", *inputs[:1], ok=False)
    assert p.returncode == 2 and "--set view01: rsaa takes its camera from each frame's sidecar" in p.stderr, p.stderr
    assert not os.path.exists(tmp_path / "d")


def test_a_sidecar_of_another_resolution_is_refused_before_the_first_output(shot, tmp_path):
    """Sidecars that give another size than their frames (another render's): a moving shot's motion
    rebuild refused the second frame after writing the first, and a still one took each sidecar's
    jitter, in pixels of the other size, without a word. Both are refused at the frame, naming both
    sizes and the sidecar."""
    _, inputs = shot
    sides = []
    for f in (1, 2):
        with open(inputs[f - 1][:-len(".exr")] + ".json") as fh:
            sides.append(json.load(fh))
    w, h = sides[0]["render_settings"]["resolution"]
    for moving in (True, False):
        d = tmp_path / ("moving" if moving else "still")
        d.mkdir()
        for f, data in zip((1, 2), json.loads(json.dumps(sides))):
            shutil.copy(inputs[f - 1], d / frame(f))
            data["render_settings"]["resolution"] = [2 * w, 2 * h]
            if not moving:  # the first frame's camera and objects: nothing moves
                data["camera"], data["objects"] = sides[0]["camera"], sides[0]["objects"]
            with open(d / frame(f, ".json"), "w") as fh:
                json.dump(data, fh)
        out = tmp_path / ("out_" + d.name)
        p = crisp("filter", "--method", "taa", "--quiet", "-o", out, d / frame(1), d / frame(2), ok=False)
        assert p.returncode == 1, (d.name, p.stderr)
        assert "the frame is %dx%d but its sidecar '%s' says %dx%d" % (w, h, d / frame(1, ".json"), 2 * w, 2 * h) \
            in p.stderr, (d.name, p.stderr)
        assert not list(out.glob("*.exr")), d.name


def test_a_sidecar_jitter_out_of_range_names_the_sidecar(shot, tmp_path):
    """A sidecar holding a jitter the filters refuse fails the run with a message that names the
    sidecar and the frame, not only the parameter."""
    _, inputs = shot
    d = tmp_path / "bad"
    d.mkdir()
    for f in (1, 2):
        shutil.copy(inputs[f - 1], d / frame(f))
        with open(inputs[f - 1][:-len(".exr")] + ".json") as fh:
            data = json.load(fh)
        if f == 2:
            data["jitter"]["x"] = 10.0
        with open(d / frame(f, ".json"), "w") as fh:
            json.dump(data, fh)
    p = crisp("filter", "--method", "taa", "--quiet", "-o", tmp_path / "out", d / frame(1), d / frame(2), ok=False)
    assert p.returncode == 1, p.stderr
    assert str(d / frame(2, ".json")) in p.stderr and str(d / frame(2)) in p.stderr, p.stderr
    assert "jitterX" in p.stderr and "out of range" in p.stderr, p.stderr
