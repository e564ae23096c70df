# SPDX-License-Identifier: Apache-2.0
"""Cross-check libcrisp's PSNR and SSIM against scikit-image.

Goes through the real shared library ($CRISP_BUILD_DIR/lib/libcrisp.so) and its
C API (crispCompareImages). The display encoding (linear clamped to [0,1],
sRGB-encoded) and the luma Y' = 0.299 R' + 0.587 G' + 0.114 B' are done here
with numpy, independently of the library, before calling scikit-image.

Tolerances: PSNR within 0.001 dB, SSIM within 1e-6 (tighter than the 0.01 dB /
1e-4 usually quoted, because we can: both sides filter in double; the only
differences are the library's float32 sRGB encoding (~1e-7 per value) and
summation order. Measured on these pairs: |dPSNR| < 1e-6 dB, |dSSIM| < 1e-8.)

Border handling: libcrisp filters the SSIM moments over the whole image with
the image mirrored at its borders (scipy.ndimage mode 'reflect', the mode
scikit-image uses) and averages the SSIM map over ALL pixels, while
structural_similarity averages only pixels at least 5 from the border (its
crop of (win_size - 1) / 2). So we check (a) the full-image figure against
the mean of scikit-image's full map (full=True), and (b) scikit-image's own
cropped figure against libcrisp called with a mask that is 1 exactly on the
cropped region.
"""
import ctypes
import os
import pathlib

import numpy as np
import pytest
from skimage.metrics import peak_signal_noise_ratio, structural_similarity

PSNR_TOL_DB = 1e-3
SSIM_TOL = 1e-6
CROP = 5  # (11 - 1) / 2


class CrispMetrics(ctypes.Structure):
    _fields_ = [(name, ctypes.c_double) for name in ("mse", "rmse", "psnr", "snr", "ssim", "flip")]


def _library_path():
    build = os.environ.get("CRISP_BUILD_DIR")
    if not build:
        pytest.fail("CRISP_BUILD_DIR is not set (run through ctest)")
    return pathlib.Path(build) / "lib" / "libcrisp.so"


@pytest.fixture(scope="module")
def crisp():
    path = _library_path()
    if not path.exists():
        pytest.fail(f"{path} does not exist: build the 'crisp' target first")
    lib = ctypes.CDLL(str(path))
    lib.crispNewContext.restype = ctypes.c_void_p
    lib.crispNewContext.argtypes = []
    lib.crispReleaseContext.argtypes = [ctypes.c_void_p]
    lib.crispCompareImages.restype = None
    lib.crispCompareImages.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int,
                                       ctypes.c_size_t, ctypes.c_size_t, ctypes.c_void_p,
                                       ctypes.POINTER(CrispMetrics)]
    lib.crispGetError.restype = ctypes.c_int
    lib.crispGetError.argtypes = [ctypes.POINTER(ctypes.c_char_p)]
    ctx = lib.crispNewContext()
    assert ctx, "crispNewContext failed"
    yield lib, ctx
    lib.crispReleaseContext(ctx)


CRISP_FORMAT_FLOAT3 = 3
CRISP_FORMAT_FLOAT4 = 4


def compare(crisp, reference, test, mask=None):
    lib, ctx = crisp
    reference = np.ascontiguousarray(reference, dtype=np.float32)
    test = np.ascontiguousarray(test, dtype=np.float32)
    height, width, channels = reference.shape
    fmt = CRISP_FORMAT_FLOAT3 if channels == 3 else CRISP_FORMAT_FLOAT4
    mask_ptr = None
    if mask is not None:
        mask = np.ascontiguousarray(mask, dtype=np.float32)
        mask_ptr = mask.ctypes.data
    out = CrispMetrics()
    lib.crispCompareImages(ctx, reference.ctypes.data, test.ctypes.data, fmt, width, height, mask_ptr,
                           ctypes.byref(out))
    message = ctypes.c_char_p()
    code = lib.crispGetError(ctypes.byref(message))
    assert code == 0, f"crispCompareImages failed: {code} {message.value}"
    return out


def display_encode(linear):
    v = np.clip(np.nan_to_num(linear[..., :3].astype(np.float64), nan=0.0), 0.0, 1.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1.0 / 2.4) - 0.055)


def luma(encoded):
    return 0.299 * encoded[..., 0] + 0.587 * encoded[..., 1] + 0.114 * encoded[..., 2]


def skimage_ssim(ref_luma, test_luma):
    return structural_similarity(ref_luma, test_luma, gaussian_weights=True, sigma=1.5,
                                 use_sample_covariance=False, data_range=1.0, full=True)


def decode(encoded):
    e = np.clip(encoded, 0.0, 1.0)
    return np.where(e <= 0.04045, e / 12.92, np.power((e + 0.055) / 1.055, 2.4))


def image_pairs():
    rng = np.random.default_rng(2024)
    h, w = 48, 64
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    pairs = {}
    # Random-ish: noise vs the same noise plus more noise.
    a = rng.uniform(0.0, 1.0, (h, w, 3))
    pairs["noise"] = (a, np.clip(a + rng.normal(0.0, 0.05, a.shape), 0.0, 1.2))
    # Structured: disk and stripes vs the same blurred-ish and shifted.
    disk = ((xx - 30) ** 2 + (yy - 20) ** 2 < 12 ** 2).astype(np.float64)
    stripes = 0.5 + 0.4 * np.sin(0.6 * xx + 0.2 * yy)
    base = np.stack([0.8 * disk + 0.1, stripes, 0.3 * disk + 0.5 * stripes], axis=-1)
    shifted = np.roll(base, 1, axis=1) * 0.9 + 0.05
    pairs["structured"] = (base, shifted)
    # HDR-ish linear values with alpha: clamping and the alpha channel must be ignored.
    hdr = rng.uniform(-0.1, 3.0, (h, w, 4))
    hdr_test = hdr.copy()
    hdr_test[..., :3] *= rng.uniform(0.8, 1.1, (h, w, 3))
    hdr_test[..., 3] = rng.uniform(0.0, 1.0, (h, w))
    pairs["hdr_rgba"] = (hdr, hdr_test)
    # Contrast loss in encoded space around mid grey.
    enc = display_encode(base)
    pairs["contrast"] = (base, decode(0.5 + 0.5 * (enc - 0.5)))
    return pairs


PAIRS = image_pairs()


@pytest.mark.parametrize("name", sorted(PAIRS))
def test_psnr_matches_skimage(crisp, name):
    reference, test = PAIRS[name]
    ours = compare(crisp, reference, test)
    expected = peak_signal_noise_ratio(display_encode(reference), display_encode(test), data_range=1.0)
    assert abs(ours.psnr - expected) < PSNR_TOL_DB, (ours.psnr, expected)
    assert ours.rmse == pytest.approx(np.sqrt(ours.mse), rel=1e-12)


@pytest.mark.parametrize("name", sorted(PAIRS))
def test_ssim_matches_skimage(crisp, name):
    reference, test = PAIRS[name]
    ref_luma, test_luma = luma(display_encode(reference)), luma(display_encode(test))
    cropped_mean, full_map = skimage_ssim(ref_luma, test_luma)
    # (a) whole image: mean of scikit-image's full (mirrored-border) map.
    ours = compare(crisp, reference, test)
    assert abs(ours.ssim - full_map.mean()) < SSIM_TOL, (ours.ssim, full_map.mean())
    # (b) scikit-image's figure: our mean restricted to its cropped region.
    mask = np.zeros(reference.shape[:2], dtype=np.float32)
    mask[CROP:-CROP, CROP:-CROP] = 1.0
    ours_cropped = compare(crisp, reference, test, mask)
    assert abs(ours_cropped.ssim - cropped_mean) < SSIM_TOL, (ours_cropped.ssim, cropped_mean)
    # The pair really differs, so the check is not 1 == 1.
    assert cropped_mean < 0.999


def test_identical_images(crisp):
    reference, _ = PAIRS["structured"]
    ours = compare(crisp, reference, reference)
    assert ours.mse == 0.0
    assert ours.psnr == 100.0
    assert ours.ssim == pytest.approx(1.0, abs=1e-12)
    assert ours.flip == 0.0


def test_size_error_is_reported(crisp):
    lib, ctx = crisp
    a = np.zeros((8, 8, 2), dtype=np.float32)  # 2 channels: not a valid format for metrics
    out = CrispMetrics()
    lib.crispCompareImages(ctx, a.ctypes.data, a.ctypes.data, 2, 8, 8, None, ctypes.byref(out))
    message = ctypes.c_char_p()
    assert lib.crispGetError(ctypes.byref(message)) != 0
    assert message.value
