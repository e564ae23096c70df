# SPDX-License-Identifier: Apache-2.0
"""The add-on's check that an EXR Blender wrote is whole before it takes its name
(addon/crisp/exr_file.py), on real files: the library's own EXRs (crisp synth, ZIP, 16 lines a
chunk) cut at every kind of place; render.py's use of it on Blender's multilayer files is tested in
tests/blender/test_render.py."""

import os
import subprocess
import sys

import pytest

from crisp_test_util import CRISP, SOURCE

sys.path.insert(0, os.path.join(SOURCE, "addon", "crisp"))
import exr_file  # noqa: E402


@pytest.fixture(scope="module")
def chart(tmp_path_factory):
    if not os.path.isfile(CRISP):
        pytest.skip("crisp CLI not built")
    out = tmp_path_factory.mktemp("chart")
    subprocess.run([CRISP, "synth", "-o", str(out), "--size", "40x35"], check=True, capture_output=True)
    return out / "chart_reference.exr"


def cut(src, dst, length):
    dst.write_bytes(src.read_bytes()[:length])
    return exr_file.incomplete(str(dst))


def test_a_whole_file_passes_and_every_cut_is_named(chart, tmp_path):
    assert exr_file.incomplete(str(chart)) is None
    data = chart.read_bytes()
    flags, attrs, pos = exr_file.read_header(data)
    assert attrs["compression"][1][0] == 3  # ZIP: 16 lines a chunk, 3 chunks for 35 rows
    assert "last chunk" in cut(chart, tmp_path / "a.exr", len(data) - 1)
    assert "never written" in cut(chart, tmp_path / "b.exr", pos + 24 + 10)  # table whole, chunks not
    assert "inside its table of 3 chunks" in cut(chart, tmp_path / "c.exr", pos + 5)
    assert "header ends early" in cut(chart, tmp_path / "d.exr", pos - 2)
    assert "not an OpenEXR file" in cut(chart, tmp_path / "e.exr", 3)
    # Every length short of the whole file is caught.
    for n in range(0, len(data), 97):
        assert cut(chart, tmp_path / "f.exr", n) is not None, n


def test_a_table_of_zeros_is_chunks_never_written(chart, tmp_path):
    """OpenEXR writes the offset table last: a writer stopped before that leaves zeros there."""
    data = bytearray(chart.read_bytes())
    _, _, pos = exr_file.read_header(data)
    data[pos:pos + 24] = bytes(24)
    broken = tmp_path / "zeros.exr"
    broken.write_bytes(bytes(data))
    assert "never written" in exr_file.incomplete(str(broken))


def test_a_long_header_is_read_past_the_first_block(tmp_path):
    """A header longer than the first read (64 KiB: many layers' channel lists) is read on."""
    name, kind = b"comments\0", b"string\0"
    text = b"x" * (70 << 10)
    header = (exr_file.MAGIC + (2).to_bytes(4, "little") + name + kind + len(text).to_bytes(4, "little") + text)
    path = tmp_path / "long.exr"
    path.write_bytes(header)  # no terminating empty name: the header runs to the end
    assert "header ends early" in exr_file.incomplete(str(path))
    path.write_bytes(header + b"\0")  # now whole, but it announces no data window
    assert "no dataWindow" in exr_file.incomplete(str(path))
