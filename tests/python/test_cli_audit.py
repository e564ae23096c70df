# SPDX-License-Identifier: Apache-2.0
"""Hostile and mistaken inputs to `crisp filter`, `info` and `compare` found by an audit of the CLI:
each failure is said before any work is lost, naming the file, and nothing read is dropped without a
word."""
import os
import re
import shutil
import signal
import subprocess
import time

import pytest

from crisp_test_util import CRISP, run_crisp as run

pytestmark = pytest.mark.skipif(not os.path.isfile(CRISP), reason="crisp CLI not built at %s" % CRISP)


def oiiotool(*args):
    subprocess.run(["oiiotool", *map(str, args)], check=True)


@pytest.fixture(scope="module")
def chart(tmp_path_factory):
    d = tmp_path_factory.mktemp("chart")
    run("synth", "-o", d, "--size", "37x23")
    return d


def test_compare_refuses_a_json_it_cannot_write_before_comparing(chart, tmp_path):
    """A --json into a missing folder, or onto a folder, used to fail only after every frame was
    compared (a long sequence's work lost); it is refused first, naming the path."""
    ref, test = chart / "chart_reference.exr", chart / "chart_1spp.exr"
    (tmp_path / "adir").mkdir()
    for target, words in ((tmp_path / "nowhere" / "m.json", "does not exist"), (tmp_path / "adir", "is a folder")):
        p = run("compare", "-q", "--reference", ref, "--test", test, "--json", target, ok=False)
        assert p.returncode == 1 and str(target) in p.stderr and words in p.stderr, p.stderr
        assert "chart_1spp" not in p.stdout, p.stdout  # nothing compared
    assert not (tmp_path / "nowhere").exists()
    p = run("compare", "-q", "--reference", ref, "--test", test, "--json", "", ok=False)
    assert p.returncode == 1 and "empty name" in p.stderr and "chart_1spp" not in p.stdout, p.stderr


def test_compare_names_a_mask_that_does_not_fit(chart, tmp_path):
    """A mask of another size than the images, or one selecting no pixel, is what is wrong: the
    error names it, not only the reference and the test."""
    ref, test = chart / "chart_reference.exr", chart / "chart_1spp.exr"
    small, empty = tmp_path / "small_mask.exr", tmp_path / "empty_mask.exr"
    oiiotool(chart / "chart_edges.exr", "--resize", "10x10", "-o", small)
    oiiotool(chart / "chart_edges.exr", "--mulc", "0", "-o", empty)
    for mask, words in ((small, "10x10"), (empty, "selects no pixel")):
        p = run("compare", "-q", "--reference", ref, "--test", test, "--mask", mask, ok=False)
        assert p.returncode == 1 and "mask '%s'" % mask in p.stderr and words in p.stderr, p.stderr


def blender_layers(chart, path, layers):
    """A multilayer EXR holding the chart's colour as each of `layers`' Combined pass."""
    names = ",".join("%s.Combined.%s" % (layer, c) for layer in layers for c in "RGBA")
    oiiotool(chart / "chart_1spp.exr", "--ch", ",".join(["R,G,B,A"] * len(layers)), "--chnames", names, "-o", path)


def test_a_second_view_layer_is_not_dropped_without_a_word(chart, tmp_path):
    """Of a multilayer EXR with two view layers (a scene with two), one is read: info names the
    other as not read, and filter says once that it is in no output."""
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    blender_layers(chart, a, ["ViewLayer", "Background"])
    blender_layers(chart, b, ["ViewLayer", "Background"])
    info = run("info", a).stdout
    assert "layer read: 'ViewLayer'" in info and "not read: layer 'Background' (4 channels)" in info, info
    p = run("filter", "-q", "--method", "fxaa", a, b, "-o", tmp_path / "out")
    assert p.stderr.count("warning") == 1, p.stderr
    assert "'%s' holds other view layers than 'ViewLayer'" % a in p.stderr and "'Background'" in p.stderr, p.stderr
    # One layer: nothing to say.
    single = tmp_path / "single.exr"
    blender_layers(chart, single, ["ViewLayer"])
    assert "not read" not in run("info", single).stdout
    assert "warning" not in run("filter", "-q", "--method", "fxaa", single, "-o", tmp_path / "out1").stderr
    # Blender's own render with its compositor on: the compositor's result beside the view layer, as
    # layer "Composite", which is no view layer left out (nothing to say; a real render's channels).
    composited = tmp_path / "composited.exr"
    blender_layers(chart, composited, ["Composite", "ViewLayer"])
    assert "not read" not in run("info", composited).stdout
    assert "warning" not in run("filter", "-q", "--method", "fxaa", composited, "-o", tmp_path / "out2").stderr


def test_a_pass_of_wrong_channels_fails_only_the_methods_that_read_it(chart, tmp_path):
    """A Vector pass of two channels (motion as some compositors write it) used to make the whole
    file unreadable: info could not list it and fxaa, which reads no motion, refused it. It is
    unusable, named by info and refused by the methods that read motion only."""
    f = tmp_path / "vector2.exr"
    oiiotool(chart / "chart_1spp.exr", "--ch", "R,G,B,A,X=1,Y=0", "--chnames",
             "ViewLayer.Combined.R,ViewLayer.Combined.G,ViewLayer.Combined.B,ViewLayer.Combined.A,"
             "ViewLayer.Vector.X,ViewLayer.Vector.Y", "-d", "float", "-o", f)
    info = run("info", f).stdout
    assert "passes: color\n" in info and "unusable: motion (pass 'ViewLayer.Vector'" in info, info
    assert "expected X,Y,Z,W" in info and "motion (unusable)" in info, info
    run("filter", "-q", "--method", "fxaa", f, "-o", tmp_path / "fxaa")
    assert (tmp_path / "fxaa" / "vector2.exr").is_file()
    p = run("filter", "-q", "--method", "taa", f, "-o", tmp_path / "taa", ok=False)
    assert p.returncode == 1 and "vector2.exr" in p.stderr and "ViewLayer.Vector" in p.stderr, p.stderr
    assert not (tmp_path / "taa").exists()


def test_a_preroll_without_frames_is_refused(chart, tmp_path):
    """--preroll warms the history of the chunk --frames picks; without --frames every input is
    written from the first, so it used to be ignored without a word (also with --resume, which
    re-reads a temporal history from the first input). It is a usage error naming both options."""
    src = chart / "chart_1spp.exr"
    for extra in ((), ("--resume",)):
        p = run("filter", "-q", "-m", "taa", "--preroll", "4", *extra, "-o", tmp_path / "out", src, ok=False)
        assert p.returncode == 2 and "--preroll" in p.stderr and "--frames" in p.stderr, p.stderr
        assert not (tmp_path / "out").exists()
    run("filter", "-q", "-m", "taa", "--frames", "1-1", "--preroll", "4", "-o", tmp_path / "out", src)
    assert (tmp_path / "out" / "chart_1spp.exr").is_file()


def test_inputs_that_are_not_regular_files_are_refused_before_they_are_opened(chart, tmp_path):
    """A named pipe called x.exr among the inputs made info and filter wait for a writer for ever;
    a socket, a device or a folder named so is no image either. Each is refused, naming the path and
    what it is, before anything is opened or written."""
    import socket
    fifo, sock, folder = tmp_path / "fifo.exr", tmp_path / "sock.exr", tmp_path / "folder.exr"
    os.mkfifo(fifo)
    server = socket.socket(socket.AF_UNIX)
    server.bind(str(sock))
    folder.mkdir()
    try:
        for path, words in ((fifo, "named pipe"), (sock, "socket"), ("/dev/null", "character device"),
                            (folder, "directory")):
            p = subprocess.run([CRISP, "info", str(path)], capture_output=True, text=True, timeout=20)
            assert p.returncode == 1 and "'%s'" % path in p.stdout and words in p.stdout, (p.stdout, p.stderr)
            out = tmp_path / "out"
            p = subprocess.run([CRISP, "filter", "-q", "-m", "fxaa", "-o", str(out), str(chart / "chart_1spp.exr"),
                                str(path)], capture_output=True, text=True, timeout=20)
            assert p.returncode == 1 and "'%s'" % path in p.stderr and words in p.stderr, p.stderr
            assert not out.exists()
    finally:
        server.close()


def interrupt_filter(src, out, started, said=None):
    """Runs crisp filter on src into out, and Ctrl-C (SIGINT) once started() is true; returns the
    exit status (-SIGINT: ended by the signal). said: a list its stderr is appended to."""
    p = subprocess.Popen([CRISP, "filter", "-q", "-m", "taa", "-o", str(out), str(src)], stderr=subprocess.PIPE,
                         text=True)
    try:
        deadline = time.monotonic() + 60
        while not started() and p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.001)
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=60)
        if said is not None:
            said.append(err)
        return p.returncode
    finally:
        if p.poll() is None:
            p.kill()


def test_ctrl_c_before_the_first_output_leaves_no_empty_output_folder(chart, tmp_path):
    """A run stopped by Ctrl-C (SIGINT) while it filtered its first frame left the output folders it
    had made behind, empty (an error did not). They are removed; a folder that was there before, or
    that holds anything, is kept. The run says where it stopped."""
    big = tmp_path / "big.exr"  # a frame that takes a while, so the signal comes before its output
    oiiotool(chart / "chart_1spp.exr", "--resize", "3200x2000", "-o", big)
    out = tmp_path / "new" / "out"
    said = []
    status = interrupt_filter(big, out, out.exists, said)
    assert status == -signal.SIGINT, status
    assert not (tmp_path / "new").exists(), os.listdir(tmp_path / "new")
    # A folder that holds something when the signal comes is kept (here: a file put in it meanwhile).
    status = interrupt_filter(big, out, lambda: out.exists() and (out / "mine.txt").write_text("mine") > 0, said)
    assert status == -signal.SIGINT and os.listdir(out) == ["mine.txt"], status
    # A folder that was there before is kept.
    there = tmp_path / "there"
    there.mkdir()
    start = time.monotonic()
    status = interrupt_filter(big, there, lambda: time.monotonic() - start > 0.3, said)
    assert status == -signal.SIGINT and there.is_dir(), status
    # Each run said once where it stopped (also under -q: a farm's log tells a cancelled task from a failed
    # one): before its input, or in it. (The third may be stopped before it says anything: its signal
    # follows the clock, not the output folder, which says the notice is in place.)
    assert len(said) == 3
    for err in said[:2] + [said[2] or said[0]]:
        assert re.fullmatch(r"filter: stopped by Ctrl-C \(SIGINT\) (before its first input: no output is written|while "
                            r"it filtered '%s' \(input 1 of 1-1\): the outputs before it are whole, and the same "
                            r"command with --resume goes on from them)\n" % re.escape(str(big)), err), err


def test_a_stop_whose_line_finds_no_reader_still_cleans_up(chart, tmp_path):
    """`crisp filter ... 2>&1 | tee log` and Ctrl-C: tee may go first, and writing the stop line to its pipe
    raised SIGPIPE, which ended crisp before it removed its new output folder. The line is lost, the
    run still ends by the Ctrl-C and leaves nothing behind."""
    big = tmp_path / "big.exr"
    oiiotool(chart / "chart_1spp.exr", "--resize", "3200x2000", "-o", big)
    out = tmp_path / "new" / "out"
    read, write = os.pipe()
    os.close(read)  # the reader is gone before the stop
    try:
        p = subprocess.Popen([CRISP, "filter", "-q", "-m", "taa", "-o", str(out), str(big)], stderr=write)
    finally:
        os.close(write)
    try:
        deadline = time.monotonic() + 60
        while not out.exists() and p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.001)
        assert p.poll() is None, "the run ended before it was stopped"
        p.send_signal(signal.SIGINT)
        assert p.wait(timeout=60) == -signal.SIGINT
    finally:
        if p.poll() is None:
            p.kill()
    assert not (tmp_path / "new").exists(), os.listdir(tmp_path / "new")


def test_files_whose_names_begin_with_a_dash_go_after_a_double_dash(chart, tmp_path, monkeypatch):
    """A path beginning with '-' read as an option, and there was no way to give it: '--' ends the
    options (what follows is a file, also '--png'), and the error for an unknown option says so."""
    monkeypatch.chdir(tmp_path)  # the relative names below begin with '-'
    shutil.copy(chart / "chart_1spp.exr", tmp_path / "-frame.exr")
    shutil.copy(chart / "chart_1spp.exr", tmp_path / "--png")
    p = run("filter", "-q", "-m", "fxaa", "-o", "out", "-frame.exr", ok=False)
    assert p.returncode == 2 and "'-frame.exr'" in p.stderr and "'--'" in p.stderr, p.stderr
    run("filter", "-q", "-m", "fxaa", "-o", "out", "--", "-frame.exr", "--png")
    assert set(os.listdir(tmp_path / "out")) == {".crisp", "--png.exr", "-frame.exr"}
    info = run("info", "--", "-frame.exr").stdout
    assert info.startswith("-frame.exr\n") and "size: 37x23" in info, info
    assert "--" in run("filter", "--help").stdout.split("Options:")[1]
    # A command without positional arguments still refuses what follows '--'.
    p = run("synth", "-o", "chart", "--", "extra", ok=False)
    assert p.returncode == 2 and "unexpected argument 'extra'" in p.stderr, p.stderr
    assert not (tmp_path / "chart").exists()


def test_a_folder_in_the_place_of_an_output_is_refused_before_the_run(chart, tmp_path):
    """A folder named like an output (OUTDIR/b.exr, or b.png with --png) failed the run only when it
    reached that frame, after the frames before it were filtered. It is refused first, naming it;
    a chunk whose outputs are not in its way runs."""
    a, b = tmp_path / "a.exr", tmp_path / "b.exr"
    shutil.copy(chart / "chart_1spp.exr", a)
    shutil.copy(chart / "chart_1spp.exr", b)
    for name, extra in (("b.exr", ()), ("b.png", ("--png",))):
        out = tmp_path / ("out_" + name.replace(".", "_"))
        (out / name).mkdir(parents=True)
        p = run("filter", "-q", "-m", "fxaa", *extra, "-o", out, a, b, ok=False)
        assert p.returncode == 1 and "'%s'" % (out / name) in p.stderr and "is a folder" in p.stderr, p.stderr
        assert os.listdir(out) == [name] and (out / name).is_dir(), os.listdir(out)  # a.exr not written
        run("filter", "-q", "-m", "fxaa", *extra, "--frames", "1-1", "-o", out, a, b)
        assert (out / "a.exr").is_file()


def test_help_and_version_refuse_arguments_they_would_drop():
    """`crisp help taa phlm` printed taa's help and dropped 'phlm'; `crisp version x` dropped 'x'. Every
    other command refuses an argument it does not take."""
    p = run("help", "taa", "phlm", ok=False)
    assert p.returncode == 2 and "unexpected argument 'phlm'" in p.stderr and not p.stdout, (p.stdout, p.stderr)
    p = run("version", "x", ok=False)
    assert p.returncode == 2 and "unexpected argument 'x'" in p.stderr and not p.stdout, (p.stdout, p.stderr)
    assert "Filter 'taa'" in run("help", "taa").stdout
    assert run("version").stdout.startswith("crisp ")
