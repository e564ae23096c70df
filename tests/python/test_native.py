# SPDX-License-Identifier: Apache-2.0
"""The add-on's ctypes layer (addon/crisp/native.py) against the real libcrisp: what it passes
through ctypes reaches the library as the caller gave it, or is refused naming the parameter."""
import ctypes
import importlib.util
import os
import pathlib

import pytest

BUILD = pathlib.Path(os.environ.get("CRISP_BUILD_DIR", pathlib.Path(__file__).resolve().parents[2] / "build"))
SOURCE = pathlib.Path(os.environ.get("CRISP_SOURCE_DIR", pathlib.Path(__file__).resolve().parents[2]))


@pytest.fixture(scope="module")
def native():
    was = os.environ.get("CRISP_LIBRARY")
    os.environ["CRISP_LIBRARY"] = str(BUILD / "lib" / "libcrisp.so")
    # native.py is pure ctypes; load it alone (the package's __init__ needs bpy).
    spec = importlib.util.spec_from_file_location("crisp_native_alone", SOURCE / "addon" / "crisp" / "native.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    yield module
    if was is None:  # the rest of the session's tests see the environment they were given
        del os.environ["CRISP_LIBRARY"]
    else:
        os.environ["CRISP_LIBRARY"] = was


@pytest.mark.parametrize("value", [2 ** 32 + 5, "4294967301", 2 ** 31, -(2 ** 32) + 7])
def test_an_int_beyond_c_int_is_refused_as_typed(native, value):
    """ctypes wraps an int beyond C int's range (2**32 + 5 arrived as 5, and maxSamples took it), so
    the add-on refuses it before the call, naming the parameter, the value given and the range."""
    assert native.check_params("taa", {"maxSamples": value}) == (
        "filter 'taa': parameter 'maxSamples' = %s is out of range [1, 65536]" % value)
    with native.Context() as ctx:
        f = native.Filter(ctx, "taa")
        try:
            with pytest.raises(native.CrispError):
                f.set_param("maxSamples", value)
            get = native.load().dll.crispGetFilterInt
            get.restype, get.argtypes = ctypes.c_int, [ctypes.c_void_p, ctypes.c_char_p]
            assert get(f.handle, b"maxSamples") == 128  # the default, untouched
        finally:
            f.close()


def test_a_float_beyond_float32_is_refused_as_typed(native):
    """ctypes rounds 1e40 to float32 infinity, which the library named as 'inf'."""
    assert native.check_params("taa", {"feedbackMax": 1e40}) == (
        "filter 'taa': parameter 'feedbackMax' = 1e+40 is out of range [0, 1]")
    assert native.check_params("taa", {"feedbackMax": "1e40"}) == (
        "filter 'taa': parameter 'feedbackMax' = 1e+40 is out of range [0, 1]")
    # Values ctypes carries as given still reach the library, which judges them.
    assert native.check_params("taa", {"maxSamples": 2 ** 31 - 1}) == (
        "filter 'taa': parameter 'maxSamples' = 2147483647 is out of range [1, 65536]")
    assert "'feedbackMax' = inf is out of range" in native.check_params("taa", {"feedbackMax": float("inf")})
    # An int beyond any double is out of range too, in words (float() raised OverflowError).
    assert native.check_params("taa", {"feedbackMax": 10 ** 400}) == (
        "filter 'taa': parameter 'feedbackMax' = %d is out of range [0, 1]" % 10 ** 400)
    assert native.check_params("taa", {"maxSamples": 65536, "feedbackMax": 1.0}) is None


@pytest.mark.parametrize("name, value, words", [
    ("maxSamples", 5.7, "takes a whole number, not '5.7'"),
    ("maxSamples", float("nan"), "takes a whole number, not 'nan'"),
    ("maxSamples", float("inf"), "takes a whole number, not 'inf'"),
    ("maxSamples", None, "takes a whole number, not 'None'"),
    ("feedbackMax", None, "takes a number, not 'None'"),
    ("feedbackMax", [1], "takes a number, not '[1]'"),
])
def test_a_value_that_is_not_the_parameters_number_is_refused(native, name, value, words):
    """check_params answers with a message, never a Python exception, and never passes on a value
    other than the one given (int() truncated 5.7 to 5, which the library then took)."""
    assert native.check_params("taa", {name: value}) == "parameter '%s' %s" % (name, words)
    assert native.check_params("taa", {"maxSamples": 5.0, "feedbackMax": 1}) is None  # whole, and an int for a float


def test_an_unknown_parameter_is_named_by_the_library_whatever_its_value(native):
    """A name the filter does not have gets the library's unknown-parameter error, which lists the
    names it has, not a range check of its own with no bounds."""
    for value in (2 ** 40, 1e40, 3):
        message = native.check_params("taa", {"bogus": value})
        assert "unknown parameter 'bogus'" in message and "out of range" not in message, message


def test_check_params_names_a_method_the_library_lacks(native):
    """check_params returns the library's message for a method it does not have, as its docstring says
    for any refusal (it raised)."""
    message = native.check_params("no-such-method", {"feedbackMin": 0.5})
    assert message and "no-such-method" in message, message


def test_a_library_of_another_version_is_refused_saying_which(native, monkeypatch):
    """A library of another major version (crisp.h: what a call means may change with it) or of an older
    minor one than the add-on needs is not loaded, and the status says which it is and what is needed;
    one of the same major and a newer minor is. (Any library with the calls' names used to load.)"""
    version = native.load().call("crispGetVersion")
    have, major, minor = native._lib.call("crispGetVersionString").decode(), version // 10000, version // 100 % 100
    monkeypatch.setattr(native, "_lib", None)
    for wanted in ((major + 1, 0), (major, minor + 1)):
        monkeypatch.setattr(native, "API_VERSION", wanted)
        monkeypatch.setattr(native, "_load_error", None)  # a failure is not retried while the file stays the same
        ok, text = native.status()
        assert not ok, wanted
        assert ("it is libcrisp %s; this add-on needs %d.x, at least %d.%d" % (have, wanted[0], wanted[0], wanted[1])
                in text), text
        assert text.startswith("libcrisp not loaded; $CRISP_LIBRARY %s" % os.environ["CRISP_LIBRARY"]), text
        assert native._lib is None
    # One of another major version that also lacks a call is named by its version, not by the call.
    monkeypatch.setattr(native, "SIGNATURES", dict(native.SIGNATURES, crispCallOfAnotherVersion=(None, [])))
    monkeypatch.setattr(native, "API_VERSION", (major + 1, 0))
    monkeypatch.setattr(native, "_load_error", None)
    ok, text = native.status()
    assert not ok and "it is libcrisp %s; this add-on needs %d.x" % (have, major + 1) in text, text
    assert "lacks" not in text, text
    monkeypatch.setattr(native, "SIGNATURES", {k: v for k, v in native.SIGNATURES.items()
                                               if k != "crispCallOfAnotherVersion"})
    monkeypatch.setattr(native, "API_VERSION", (major, 0))
    monkeypatch.setattr(native, "_load_error", None)
    assert native.status()[0]


def test_a_failed_load_is_retried_only_when_the_file_or_path_changes(native, monkeypatch, tmp_path):
    """The panel asks native.status() on every redraw: a library that failed to load is not hashed and
    opened again each time (it was), but is again once its file changes (a rebuild: another modification
    time or size) or another path is given."""
    bad = tmp_path / "libcrisp.so"
    bad.write_bytes(b"not a library")
    monkeypatch.setattr(native, "_lib", None)
    monkeypatch.setattr(native, "_load_error", None)
    monkeypatch.setenv("CRISP_LIBRARY", str(bad))
    hashed = []
    digest = native._file_digest
    monkeypatch.setattr(native, "_file_digest", lambda path: hashed.append(path) or digest(path))

    def fails():
        ok, text = native.status()
        assert not ok
        return text

    first = fails()
    assert first.startswith("libcrisp not loaded; $CRISP_LIBRARY %s: " % bad), first
    assert [fails() for _ in range(5)] == [first] * 5
    assert hashed == [str(bad)], "retried on every call"
    st = bad.stat()
    os.utime(bad, ns=(st.st_atime_ns, st.st_mtime_ns + 10 ** 9))  # rebuilt: another modification time
    fails()
    assert len(hashed) == 2
    bad.write_bytes(b"not a library either")  # another size
    os.utime(bad, ns=(st.st_atime_ns, st.st_mtime_ns + 10 ** 9))
    fails()
    assert len(hashed) == 3
    fails()
    assert len(hashed) == 3
    other = tmp_path / "elsewhere.so"  # another path
    monkeypatch.setenv("CRISP_LIBRARY", str(other))
    assert "$CRISP_LIBRARY %s: no such file" % other in fails()
    other.write_bytes(b"\0")  # a file where there was none
    fails()
    assert hashed[-1] == str(other) and len(hashed) == 4
    monkeypatch.setenv("CRISP_LIBRARY", str(BUILD / "lib" / "libcrisp.so"))
    assert native.status()[0]


def test_a_value_spelt_otherwise_is_recorded_as_the_same_setting(native):
    """A frame's made_with records parameters in one spelling (canonical_param_texts), so a resume
    sees the panel's float32 0.99 (0.9900000095367432 as Python holds it), a farm job's --set 0.99 and
    0.990 as the same setting, and a bool's 1 and True; another value stays another."""
    panel = ctypes.c_float(0.99).value
    assert panel != 0.99
    same = [native.canonical_param_texts("phlm", {"lambda": v, "footprintBox": b})
            for v, b in ((panel, False), ("0.99", "false"), (" 0.990", "0"), ("9.9e-1", "off"))]
    assert same == [{"lambda": "0.99", "footprintBox": "false"}] * 4, same
    assert native.canonical_param_texts("phlm", {"lambda": "0.991"}) == {"lambda": "0.991"}
    assert native.canonical_param_texts("taa", {"maxSamples": "064", "clipSpace": "rgb"}) == {
        "maxSamples": "64", "clipSpace": "rgb"}
    assert native.canonical_param_texts("taa", {"maxSamples": "many"}) == {"maxSamples": "many"}


def test_a_numpy_number_is_taken_as_the_number_it_is(native):
    """A numpy scalar (a compositor's or farm tool's values often are: np.float32 from an array, np.int64
    from a frame range) is a number: it was refused as 'takes a number, not '0.5'' because only Python's
    int and float were counted as numbers. Its value still goes through the same checks."""
    np = pytest.importorskip("numpy")
    assert native.check_params("taa", {"maxSamples": np.int64(64), "feedbackMin": np.float64(0.5),
                                       "feedbackMax": np.float32(0.75), "jitterX": np.float32(0.25),
                                       "staticClip": np.bool_(True)}) is None
    assert native.check_params("taa", {"maxSamples": np.float32(64.0)}) is None  # whole, as 64.0 is
    assert native.check_params("taa", {"maxSamples": np.float32(5.5)}) == (
        "parameter 'maxSamples' takes a whole number, not '5.5'")
    assert native.check_params("taa", {"maxSamples": np.int64(2 ** 32 + 5)}) == (
        "filter 'taa': parameter 'maxSamples' = %d is out of range [1, 65536]" % (2 ** 32 + 5))
    with native.Context() as ctx:
        f = native.Filter(ctx, "taa")
        try:
            f.set_param("jitterX", np.float32(0.25))
            f.set_param("maxSamples", np.uint16(32))
            get_float = native.load().dll.crispGetFilterFloat
            get_float.restype, get_float.argtypes = ctypes.c_float, [ctypes.c_void_p, ctypes.c_char_p]
            get_int = native.load().dll.crispGetFilterInt
            get_int.restype, get_int.argtypes = ctypes.c_int, [ctypes.c_void_p, ctypes.c_char_p]
            assert (get_float(f.handle, b"jitterX"), get_int(f.handle, b"maxSamples")) == (0.25, 32)
        finally:
            f.close()


@pytest.mark.parametrize("method, params, threads", [
    ("taa", {"maxSamples": 0}, 0),       # a parameter the library refuses
    ("taa", {"noSuchParameter": 1}, 0),  # a name it does not know
    ("bogus", None, 0),                  # a method it does not have
    ("taa", None, 5000),                 # a thread count it refuses (the context's own setting)
])
def test_a_frame_filter_that_fails_to_start_releases_its_handles(native, monkeypatch, method, params, threads):
    """FrameFilter (and Context) raised from __init__ with the context and filter they had made still
    held: nothing could release them (the caller never got the object), so a long-running tool leaked a
    context and a filter for every job started with a setting the library refused."""
    held = []
    call = native.call

    def counting(name, *args):
        result = call(name, *args)
        if name in ("crispNewContext", "crispNewFilter"):
            held.append(result)
        elif name in ("crispReleaseContext", "crispReleaseFilter"):
            held.remove(args[0])
        return result

    monkeypatch.setattr(native, "call", counting)
    with pytest.raises(native.CrispError):
        native.FrameFilter(method, params, threads)
    assert held == []
    native.FrameFilter("taa", {"maxSamples": 8}).close()  # one that starts releases both on close
    assert held == []


def test_handles_dropped_without_close_are_released_once_when_collected(native, monkeypatch, tmp_path):
    """A script that drops a Context, Filter, Frame or FrameFilter without close() (or loses it to an
    exception between making and closing it) kept its handle open for the life of the process. Python
    now releases it when it collects the object, as it closes a dropped file; an object closed first is
    not released a second time."""
    import gc
    made, released = [], []
    call = native.call

    def counting(name, *args):
        result = call(name, *args)
        if name in ("crispNewContext", "crispNewFilter", "crispLoadFrame"):
            made.append(result)
        elif name in ("crispReleaseContext", "crispReleaseFilter", "crispReleaseFrame"):
            released.append(args[0])
        return result

    monkeypatch.setattr(native, "call", counting)
    path = str(tmp_path / "frame.exr")
    rgba = (ctypes.c_float * 4)(0.5, 0.5, 0.5, 1.0)
    with native.Context() as ctx:
        native.write_image(ctx, path, ctypes.addressof(rgba), native.FORMAT_FLOAT4, 1, 1)
    made.clear(), released.clear()

    def drop():  # every object made and dropped unclosed
        context = native.Context()
        taa = native.Filter(context, "taa")
        native.Frame(context, path)
        native.FrameFilter("fxaa")
        del context  # before its filter, which keeps it alive in the library
        taa.set_param("maxSamples", 8)
        del taa
    drop()
    gc.collect()
    assert len(made) == 5 and sorted(released) == sorted(made)

    made.clear(), released.clear()
    with native.Context() as context:  # closed on time: released there, and not again when collected
        native.Filter(context, "taa").close()
        native.FrameFilter("fxaa").close()
    del context
    gc.collect()
    assert len(made) == 4 and sorted(released) == sorted(made)


def _write_frame(native, path, value=0.5):
    """A 4x3 RGBA frame of one value, written by the library."""
    rgba = (ctypes.c_float * (4 * 3 * 4))(*([value] * 48))
    with native.Context() as ctx:
        native.write_image(ctx, str(path), ctypes.addressof(rgba), native.FORMAT_FLOAT4, 4, 3)


@pytest.mark.parametrize("sidecars", [
    # Without "frame": the next frame's check added 1 to the missing number (TypeError, the sequence stopped).
    [{"camera": {"name": "Cam"}, "jitter": {"x": 0.1, "y": 0}},
     {"frame": 2, "camera": {"name": "Cam"}, "jitter": {"x": -0.1, "y": 0}},
     {"frame": 3, "camera": {"name": "Cam"}, "jitter": {"x": 0, "y": 0}}],
    # A frame number or camera name of another type (a string, a list, a bool): TypeError or AttributeError.
    [{"frame": "1", "camera": ["Cam"], "jitter": {"x": 0.1, "y": 0}},
     {"frame": 2, "camera": {"name": 7}, "jitter": {"x": -0.1, "y": 0}},
     {"frame": True, "camera": {"name": "Cam"}, "jitter": {"x": 0, "y": 0}}],
], ids=["missing", "other_types"])
def test_a_sidecar_frame_or_camera_left_out_or_of_another_type_says_nothing(native, tmp_path, sidecars):
    """FrameFilter reads each frame's position and camera from its sidecar; a frame number or camera name
    left out or of another type says nothing, so history carries over to the frame after it (as after a
    frame without a sidecar) rather than an exception stopping the sequence."""
    import json
    ff = native.FrameFilter("taa", None, 1)
    try:
        for i, side in enumerate(sidecars, 1):
            exr = tmp_path / ("frame_%04d.exr" % i)
            _write_frame(native, exr)
            (tmp_path / ("frame_%04d.json" % i)).write_text(json.dumps(side))
            ff.run(str(exr), [str(tmp_path / ("out_%04d.exr" % i))])
            assert ff.restart_reason is None, i
    finally:
        ff.close()


@pytest.mark.parametrize("method", ["taa", "fxaa"])
def test_a_frame_filter_holds_no_image_of_a_frame_it_freed(native, tmp_path, method):
    """FrameFilter.run frees each frame when it is done with it. The filter kept the frame's passes bound
    after that, so a commit and execute between frames (a caller's, or a run that failed before binding
    them all) read freed memory. Now every image is unbound when a run ends, however it ends: the next
    commit names the missing colour, and the next frame filters as if nothing had happened."""
    exr = tmp_path / "frame_0001.exr"
    _write_frame(native, exr)
    ff = native.FrameFilter(method, None, 1, ("color",))
    try:
        ff.run(str(exr), [str(tmp_path / "out.exr")])
        with pytest.raises(native.CrispError, match="required image 'color' .* is not set"):
            ff.filter.commit()
        if method == "taa":  # a frame without the depth pass the plan lists: refused, and nothing stays bound
            ff.passes = ["color", "depth"]
            with pytest.raises(native.CrispError, match="depth"):
                ff.run(str(exr), [str(tmp_path / "out2.exr")])
            with pytest.raises(native.CrispError, match="required image 'color' .* is not set"):
                ff.filter.commit()
            ff.passes = ["color"]
        ff.run(str(exr), [str(tmp_path / "out3.exr")])
        pixels, size = ff.output_bottom_up()
        assert size == (4, 3) and float(pixels[0]) == pytest.approx(0.5, rel=1e-6)
    finally:
        ff.close()


@pytest.mark.parametrize("text, says", [
    ('{"frame": 1, "jitter": {"x": 0.1', "cannot be read"),                     # cut short
    ('[1, 2]', "is not a JSON object"),
    (b'{"frame": 1, "jitter": {"x": 0.1, "y": 0}, "camera": {"name": "\xff"}}', "cannot be read"),  # not UTF-8
    ('{"frame": 1, "jitter": [0.1, 0]}', "key 'jitter' is not a JSON object"),
    ('{"frame": 1, "jitter": {"x": "0.1", "y": 0}}', "key 'jitter.x' is not a finite number ('0.1')"),
    ('{"frame": 1, "jitter": {"x": 0.1, "y": 1e999}}', "key 'jitter.y' is not a finite number (inf)"),
    ('{"frame": 1, "jitter": {"x": true, "y": 0}}', "key 'jitter.x' is not a finite number (True)"),
    ('{"frame": 1, "jitter": false}', "key 'jitter' is not a JSON object"),    # was read as no jitter
    ('{"frame": 1, "jitter": {"x": 1%s, "y": 0}}' % ("0" * 400), "key 'jitter.x' is not a finite number (1000"),
    ("[" * 100000 + "]" * 100000, "cannot be read"),                          # RecursionError in json
])
def test_a_broken_sidecar_is_named_with_what_is_wrong(native, tmp_path, text, says):
    """A temporal filter reads each frame's jitter from its sidecar. A broken one raised Python's own
    error (JSONDecodeError, "could not convert string to float", AttributeError of a list), naming
    neither the file nor the key; now a CrispError names both, as the library's reader does."""
    exr = tmp_path / "frame_0001.exr"
    _write_frame(native, exr)
    sidecar = tmp_path / "frame_0001.json"
    sidecar.write_bytes(text if isinstance(text, bytes) else text.encode())
    ff = native.FrameFilter("taa", None, 1)
    try:
        with pytest.raises(native.CrispError) as e:
            ff.run(str(exr), [str(tmp_path / "out.exr")])
        assert str(e.value).startswith("sidecar '%s': " % sidecar), str(e.value)
        assert says in str(e.value), str(e.value)
        assert not (tmp_path / "out.exr").exists()
    finally:
        ff.close()


def test_a_relative_crisp_library_path_loads_that_file(native, monkeypatch, tmp_path):
    """$CRISP_LIBRARY=libcrisp.so (a file in the working folder) was checked as that file but handed to
    dlopen as a bare name, which searches the system's library folders instead: the load failed with "no
    such file" beside a file that is there (or would load another libcrisp than the one hashed)."""
    import shutil
    shutil.copy(BUILD / "lib" / "libcrisp.so", tmp_path / "libcrisp.so")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("CRISP_LIBRARY", "libcrisp.so")
    monkeypatch.setattr(native, "_lib", None)
    monkeypatch.setattr(native, "_load_error", None)
    ok, text = native.status()
    assert ok, text
    assert native._lib.path == str(tmp_path / "libcrisp.so")


@pytest.mark.parametrize("threads", [2 ** 32 + 2, -(2 ** 32) + 4])
def test_a_thread_count_beyond_c_int_is_refused_as_typed(native, threads):
    """ctypes wraps an int beyond C int's range: Context(threads=2**32 + 2) ran on 2 threads, and the
    library's own range check saw only the wrapped value. It is refused as given, in the library's words."""
    with pytest.raises(native.CrispError) as e:
        native.Context(threads=threads)
    assert e.value.detail.startswith("context parameter 'numThreads' = %d is out of range" % threads), e.value.detail


@pytest.mark.parametrize("width, height", [(2 ** 64 + 2, 2), (2, 2 ** 64 + 2), (-2, 2)])
def test_an_image_size_ctypes_would_wrap_is_refused_as_typed(native, width, height):
    """ctypes wraps an int beyond size_t: set_image with a width of 2**64 + 2 set a 2-pixel-wide image
    (and -2 arrived as 18446744073709551614). The size is refused as given, naming the image."""
    buf = (ctypes.c_float * 16)()
    with native.Context() as ctx:
        f = native.Filter(ctx, "none")
        try:
            with pytest.raises(native.CrispError) as e:
                f.set_image("color", ctypes.addressof(buf), native.FORMAT_FLOAT4, width, height)
            assert e.value.detail == "image 'color': size %dx%d is out of range [1, 65536]" % (width, height)
            f.set_image("output", ctypes.addressof(buf), native.FORMAT_FLOAT4, 2, 2)
            with pytest.raises(native.CrispError, match="required image 'color'"):
                f.commit()  # nothing was set as the colour
        finally:
            f.close()


def test_formats_sizes_switches_and_threads_ctypes_or_python_would_change_are_refused(native, tmp_path):
    """Values ctypes wraps or Python coerces before the library sees them: a format of 2**32 + 4 reached
    it as 4 (float4) and was taken, write_image wrote a width of 2**64 + 2 as 2, a switch took None,
    0.5, NaN or [0] through bool(), and Context(threads=0.5) meant every core. Each is refused as given,
    naming it; True, False, 0, 1 and a whole float of threads are taken."""
    buf = (ctypes.c_float * 16)()
    path = str(tmp_path / "w.exr")
    with native.Context() as ctx:
        f = native.Filter(ctx, "taa")
        try:
            for fmt in (2 ** 32 + 4, -2 ** 31 - 1, 4.0, None):
                with pytest.raises(native.CrispError) as e:
                    f.set_image("color", ctypes.addressof(buf), fmt, 2, 2)
                assert e.value.detail == "image 'color': unknown format %s" % fmt
            with pytest.raises(native.CrispError) as e:
                native.write_image(ctx, path, ctypes.addressof(buf), native.FORMAT_FLOAT4, 2 ** 64 + 2, 2)
            assert e.value.detail == "file '%s': size %dx2 is out of range [1, 65536]" % (path, 2 ** 64 + 2)
            assert not os.path.exists(path)
            for value in (None, 0.5, float("nan"), [0], "maybe"):
                with pytest.raises(native.CrispError) as e:
                    f.set_param("staticClip", value)
                assert "parameter 'staticClip'" in e.value.detail, value
            for value in (True, False, 0, 1):
                f.set_param("staticClip", value)
        finally:
            f.close()
    for threads in (0.5, 3.9):
        with pytest.raises(native.CrispError) as e:
            native.Context(threads=threads)
        assert e.value.detail == "context parameter 'numThreads' takes a whole number, not '%s'" % threads
    native.Context(threads=2.0).close()


def test_a_path_that_is_not_utf8_reaches_the_library(native, tmp_path):
    """A file name that is not UTF-8 (Latin-1 on an old share) comes from os.listdir as a str with
    surrogate escapes; it was encoded as UTF-8 (UnicodeEncodeError: the frame could not be named). Paths
    are encoded as the file system does (os.fsencode), so the library opens the file that is there."""
    name = os.fsencode(str(tmp_path)) + b"/caf\xe9.exr"
    rgba = (ctypes.c_float * (2 * 2 * 4))(*([0.25] * 16))
    with native.Context() as ctx:
        native.write_image(ctx, name, ctypes.addressof(rgba), native.FORMAT_FLOAT4, 2, 2)
        listed = [p for p in os.listdir(str(tmp_path)) if p.endswith(".exr")]
        assert listed == [os.fsdecode(b"caf\xe9.exr")]
        with native.Frame(ctx, os.path.join(str(tmp_path), listed[0])) as frame:
            assert (frame.width, frame.height) == (2, 2)


def test_a_name_with_a_nul_is_refused_not_cut_short(native, tmp_path):
    """ctypes passes a str with an embedded NUL as a C string that ends there: "maxSamples\\0junk" set
    maxSamples, and "out.exr\\0.png" wrote out.exr. Such a name is refused (as Python's open() does)."""
    rgba = (ctypes.c_float * 4)(0.5, 0.5, 0.5, 1.0)
    with native.Context() as ctx:
        f = native.Filter(ctx, "taa")
        try:
            with pytest.raises(native.CrispError, match="NUL"):
                f.set_param("maxSamples\0junk", 5)
            get = native.load().dll.crispGetFilterInt
            get.restype, get.argtypes = ctypes.c_int, [ctypes.c_void_p, ctypes.c_char_p]
            assert get(f.handle, b"maxSamples") == 128
        finally:
            f.close()
        with pytest.raises(native.CrispError, match="NUL"):
            native.write_image(ctx, str(tmp_path / "out.exr\0.png"), ctypes.addressof(rgba), native.FORMAT_FLOAT4, 1, 1)
    assert os.listdir(str(tmp_path)) == []


def test_a_frame_lists_the_sub_samples_it_holds_after_a_refused_camera(native, tmp_path):
    """crispAttachFrameSubsamples with a filter reads the sub-sample files into the frame, then sets the
    filter's camera from the sidecar. A camera the filter refuses (a view term beyond +-1000) failed the
    call after the passes were added, and crispGetFramePasses went on listing the passes from before:
    "subsamples" was in the frame (crispGetFramePass returned it) but not in its list."""
    import json
    oiio = pytest.importorskip("OpenImageIO")
    np = pytest.importorskip("numpy")
    w, h = 6, 4
    names = ["ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B", "ViewLayer.Combined.A",
             "ViewLayer.Depth.Z", "ViewLayer.Normal.X", "ViewLayer.Normal.Y", "ViewLayer.Normal.Z"]
    pixel = np.array([0.5, 0.5, 0.5, 1.0, 10.0, 0.0, 0.0, 1.0], dtype=np.float32)
    for stem in ["frame_0001"] + ["frame_0001_sub%d" % k for k in range(8)]:
        spec = oiio.ImageSpec(w, h, len(names), oiio.FLOAT)
        spec.channelnames = names
        out = oiio.ImageOutput.create(str(tmp_path / (stem + ".exr")))
        assert out.open(str(tmp_path / (stem + ".exr")), spec), oiio.geterror()
        assert out.write_image(np.tile(pixel, (h, w, 1)))
        out.close()
    xs = [-0.375, 0.125, 0.375, -0.125, -0.25, 0.25, 0.25, -0.25]
    ys = [-0.125, -0.375, 0.125, 0.375, 0.25, 0.25, -0.25, -0.25]  # y up, as the add-on writes them
    (tmp_path / "frame_0001.json").write_text(json.dumps({
        "frame": 1, "render_settings": {"resolution": [w, h]}, "jitter": {"x": 0, "y": 0}, "objects": {},
        "camera": {"view": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 2000, 0], [0, 0, 0, 1]],
                   "projection": [[2, 0, 0, 0], [0, 3, 0, 0], [0, 0, -1, -0.2], [0, 0, -1, 0]],
                   "projection_unjittered": [[2, 0, 0, 0], [0, 3, 0, 0], [0, 0, -1, -0.2], [0, 0, -1, 0]]},
        "subsamples": [{"offset": [x, y], "file": "frame_0001_sub%d.exr" % k} for k, (x, y) in enumerate(zip(xs, ys))]}))
    with native.Context() as ctx, native.Frame(ctx, str(tmp_path / "frame_0001.exr")) as frame:
        f = native.Filter(ctx, "rsaa")
        try:
            with pytest.raises(native.CrispError, match="view22"):
                frame.attach_subsamples(ctx, f)
            # Nor did the filter take the rest of that camera (RsaaFiles.RefusedCameraChangesNoParameter).
            get = native.load().dll.crispGetFilterFloat
            get.restype, get.argtypes = ctypes.c_float, [ctypes.c_void_p, ctypes.c_char_p]
            assert (get(f.handle, b"proj00"), get(f.handle, b"proj11")) == (1.0, 1.0)
        finally:
            f.close()
        assert frame.pass_pointer("subsamples")[1] == native.FORMAT_RSAA_SUBSAMPLES  # it holds them...
        assert "subsamples" in frame.passes()  # ...and lists them


def test_a_frame_filter_writes_while_its_caller_works_and_says_what_failed(native, monkeypatch, tmp_path):
    """FrameFilter.run(..., while_writing=f) writes the outputs on a thread of its own while f runs (the
    add-on makes the PNG then): each waits for the other to have started, which fails if they run one
    after the other; f sees the frame's output; run returns only when both have ended, raising the
    writer's error first, else f's."""
    import threading
    rgba = (ctypes.c_float * (4 * 3 * 4))(*([0.25] * 48))
    exr = tmp_path / "frame_0001.exr"
    with native.Context() as ctx:
        native.write_image(ctx, str(exr), ctypes.addressof(rgba), native.FORMAT_FLOAT4, 4, 3)
    writing, working = threading.Event(), threading.Event()
    real_write = native.write_image

    def write_image(*args):
        writing.set()
        assert working.wait(10), "the caller's work did not run while the outputs were written"
        real_write(*args)
    monkeypatch.setattr(native, "write_image", write_image)
    seen = []

    def foreground():
        working.set()
        assert writing.wait(10), "the outputs were not written while the caller worked"
        pixels, size = ff.output_bottom_up()
        seen.append((size, float(pixels[0])))

    def fails():
        raise ValueError("png failed")
    ff = native.FrameFilter("none", None, 1)
    try:
        ff.run(str(exr), [str(tmp_path / "out.exr")], while_writing=foreground)
        assert seen == [((4, 3), 0.25)]
        assert (tmp_path / "out.exr").is_file()
        with pytest.raises(ValueError, match="png failed"):
            ff.run(str(exr), [str(tmp_path / "out2.exr")], while_writing=fails)
        assert (tmp_path / "out2.exr").is_file(), "the write ran to its end"
        # A folder where the output goes: the writer fails, and its error wins over the caller's.
        (tmp_path / "taken.exr").mkdir()
        with pytest.raises(native.CrispError, match="taken.exr"):
            ff.run(str(exr), [str(tmp_path / "taken.exr")], while_writing=fails)
    finally:
        ff.close()
