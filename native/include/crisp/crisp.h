// SPDX-License-Identifier: Apache-2.0
// Crisp: anti-aliasing filters for 1-sample renders. Public C API.
//
// Shape (after Intel Open Image Denoise): opaque handles; images and parameters
// set by name so new ones never change the ABI; lifecycle
// new -> set -> commit -> execute -> release. Errors are kept per thread as the
// first unqueried error: every call that fails records one, and
// crispGetError() returns it and clears it. No C++ exception crosses this API.
//
// Image convention (see native/core/conventions.h): rows top-down (row 0 is the
// top of the picture, as stored in EXR), x to the right, linear scene-referred
// colour, planar camera depth, motion in pixels as (previous - current) with y
// DOWN, object IDs as the 32-bit Cryptomatte hash (0 = background).
#ifndef CRISP_H
#define CRISP_H

#include <stddef.h>
#include <stdint.h>

#if defined(_WIN32)
#  if defined(CRISP_BUILDING_LIBRARY)
#    define CRISP_API __declspec(dllexport)
#  else
#    define CRISP_API __declspec(dllimport)
#  endif
#else
#  define CRISP_API __attribute__((visibility("default")))
#endif

#ifdef __cplusplus
extern "C" {
#endif

#define CRISP_VERSION_MAJOR 0
#define CRISP_VERSION_MINOR 2
#define CRISP_VERSION_PATCH 0
#define CRISP_VERSION (CRISP_VERSION_MAJOR * 10000 + CRISP_VERSION_MINOR * 100 + CRISP_VERSION_PATCH)

typedef enum CrispError {
  CRISP_ERROR_NONE = 0,
  CRISP_ERROR_UNKNOWN = 1,
  CRISP_ERROR_INVALID_ARGUMENT = 2,   // bad name, value, format (channel count), image size,
                                      // stride or alignment, or a NULL handle
  CRISP_ERROR_INVALID_OPERATION = 3,  // wrong order (execute before commit, ...)
  CRISP_ERROR_OUT_OF_MEMORY = 4,
  CRISP_ERROR_IO = 5,                 // unreadable, truncated or corrupt file
  CRISP_ERROR_INVALID_DATA = 6        // at commit: a required image not set, images of
                                      // different sizes; a file's missing or unusable pass
} CrispError;

typedef enum CrispFormat {
  CRISP_FORMAT_UNDEFINED = 0,
  CRISP_FORMAT_FLOAT = 1,   // 1 x float32
  CRISP_FORMAT_FLOAT2 = 2,
  CRISP_FORMAT_FLOAT3 = 3,
  CRISP_FORMAT_FLOAT4 = 4,
  CRISP_FORMAT_UINT = 5,    // 1 x uint32 (object ID hash); an ID image may also be
                            // CRISP_FORMAT_FLOAT, read as its bits (Cryptomatte's hash)
  // RSAA's 8 geometric sub-samples of one pixel in one 80-byte record: float32
  // planar depth[8], then int16 world normal x[8], y[8], z[8] (snorm:
  // component x 32767, rounded). The rsaa filter's image "subsamples";
  // crispAttachFrameSubsamples makes it.
  CRISP_FORMAT_RSAA_SUBSAMPLES = 6,
  // Never formats: make the enum a signed 32-bit one, so any int a C caller passes,
  // negative ones too, is a value of it (in C++ a value outside an enum's range is
  // undefined), refused as an unknown format (INVALID_ARGUMENT).
  CRISP_FORMAT_MIN_ENUM_ = -0x7FFFFFFF - 1,
  CRISP_FORMAT_MAX_ENUM_ = 0x7FFFFFFF
} CrispFormat;

typedef struct CrispContextImpl* CrispContext;
typedef struct CrispFilterImpl* CrispFilter;
typedef struct CrispFrameImpl* CrispFrame;

// ---- version and errors ---------------------------------------------------
CRISP_API int crispGetVersion(void);                 // CRISP_VERSION of the loaded library
CRISP_API const char* crispGetVersionString(void);   // "0.2.0"
// Returns the first error recorded on this thread since the last query and
// clears it. *outMessage (if not NULL) points to a thread-local string valid
// until the next Crisp call on this thread, or is set to NULL when there is
// no error (CRISP_ERROR_NONE). An error on one thread is never seen on another.
CRISP_API CrispError crispGetError(const char** outMessage);

// ---- threads and handles ----------------------------------------------------
// A context may be shared by filters running on several threads; each filter
// (and frame) is used by one thread at a time. Set the context's parameters
// before its filters run: a change while one executes is a data race. A filter
// keeps its context alive, so the two may be released in either order.
// Releasing a handle more often than it was made and retained, or using it
// after its last release, is undefined. Releasing NULL does nothing and
// records no error, as free(NULL): cleanup code need not test its handles.

// ---- context --------------------------------------------------------------
// Parameters: "numThreads" (int, 0 = all cores; used from the next execute of
// every filter of the context, no commit needed), "verbose" (int 0..2;
// checked and kept, nothing is printed yet). crispGetContextInt also reads
// "version" (CRISP_VERSION). crispCommitContext has nothing to apply (the
// parameters act at once); it is kept for the OIDN shape.
CRISP_API CrispContext crispNewContext(void);
CRISP_API void crispRetainContext(CrispContext context);
CRISP_API void crispReleaseContext(CrispContext context);
CRISP_API void crispSetContextInt(CrispContext context, const char* name, int value);
CRISP_API int crispGetContextInt(CrispContext context, const char* name);
CRISP_API void crispCommitContext(CrispContext context);

// ---- filters --------------------------------------------------------------
// Types: "none", "fxaa", "repair", "rsaa" (spatial: each frame alone) and
// "taa", "taa-improved", "phlm" (temporal). crispGetFilterTypes returns them
// as a comma-separated list.
CRISP_API const char* crispGetFilterTypes(void);
CRISP_API CrispFilter crispNewFilter(CrispContext context, const char* type);
CRISP_API void crispRetainFilter(CrispFilter filter);
CRISP_API void crispReleaseFilter(CrispFilter filter);

// Non-owning strided view. pixelByteStride/rowByteStride 0 = packed. The
// pointer and both strides must be multiples of 4 bytes (values are read as
// 32-bit floats or integers), the strides at least a pixel and a row.
// Passing ptr = NULL unsets the image. The "output" image may share an input's
// buffer (in place): the result is the same as with separate buffers.
CRISP_API void crispSetFilterImage(CrispFilter filter, const char* name, void* ptr,
                                   CrispFormat format, size_t width, size_t height,
                                   size_t pixelByteStride, size_t rowByteStride);
CRISP_API void crispUnsetFilterImage(CrispFilter filter, const char* name);

// Each parameter has one type (crispGetFilterInfo); crispSetFilterInt also
// sets a float parameter. Any other mismatch is INVALID_ARGUMENT.
CRISP_API void crispSetFilterInt(CrispFilter filter, const char* name, int value);
CRISP_API void crispSetFilterFloat(CrispFilter filter, const char* name, float value);
CRISP_API void crispSetFilterBool(CrispFilter filter, const char* name, int value);
CRISP_API void crispSetFilterString(CrispFilter filter, const char* name, const char* value);
CRISP_API int crispGetFilterInt(CrispFilter filter, const char* name);
CRISP_API float crispGetFilterFloat(CrispFilter filter, const char* name);
CRISP_API int crispGetFilterBool(CrispFilter filter, const char* name);
// Returned string is valid until the filter is changed or released.
CRISP_API const char* crispGetFilterString(CrispFilter filter, const char* name);
// Human-readable table of the filter's parameters and image roles.
CRISP_API const char* crispGetFilterDoc(CrispFilter filter);
// The same as JSON, for programs (the Blender add-on builds its settings from
// it): {"type": ..., "images": [{"name", "required", "minChannels",
// "maxChannels", "uint" (an ID image: UINT, or FLOAT read as its bits),
// "meaning"}...], "params": [{"name", "type" (int,
// float, bool, string), "default", "min", "max" | "choices", "meaning",
// "source"}...]}. Valid until the filter is changed or released.
CRISP_API const char* crispGetFilterInfo(CrispFilter filter);

// Validates images and parameters and allocates what execute needs. Needed
// again after a parameter is set or an image changes size or format, is unset
// or is first set; re-pointing an image of the same size and format is not a
// change. Until then execute fails (INVALID_OPERATION) naming the first change.
CRISP_API void crispCommitFilter(CrispFilter filter);
// Runs one frame. Allocates no image-sized memory, except on the first in-place
// run of a size (a copy of the inputs the output overwrites, kept for the next
// frames) and, for "taa", "taa-improved" and "phlm", on the first frame of a
// size whose colour's alpha is below 1 somewhere (the alpha's history, about
// 150 MB at 1920x1080, kept until the size changes, a reset included); small
// blocks (per-row scratch, the thread pool's tasks) may be.
// Temporal filters keep history between calls (below). Every filter's output
// is finite: a colour value that is NaN reads as 0, one beyond +-65504 (+-Inf
// included) as +-65504 (the fuzz targets check it for every filter:
// tests/fuzz/fuzz_filters.cpp and fuzz_c_api.cpp).
CRISP_API void crispExecuteFilter(CrispFilter filter);
// Forgets temporal history: call it at a camera cut, a jump in time or a
// change of lighting; the next frame is filtered as a first frame.
CRISP_API void crispResetFilter(CrispFilter filter);
// History of the temporal filters between executes. Kept: across re-commits
// for a new jitter or other parameters, and when an optional image
// ("motion", "depth"; taa-improved's "id", "albedo") appears or goes (the
// frame after depth appears has no previous depth, so it skips the
// disocclusion test). Dropped (the next frame is a first frame):
// crispResetFilter, a new size, and for "taa" and "taa-improved" a new
// "clipSpace" (the history is stored in it). A filter is not told of a cut
// by its images: without crispResetFilter only the clip box and the depth
// test keep the old shot out of the new one.

// ---- frames: reading passes from files -----------------------------------
// Reads a Blender multilayer EXR (Combined, Depth.Z, Normal, Vector, DiffCol,
// CryptoObject00..) or a plain RGB(A) EXR/PNG into owned buffers converted to
// the library's convention. Of a multi-part EXR each pass is read from the part
// that holds it (the README says how); a pass in two parts is an error.
CRISP_API CrispFrame crispLoadFrame(CrispContext context, const char* path);
CRISP_API void crispReleaseFrame(CrispFrame frame);
CRISP_API int crispGetFrameWidth(CrispFrame frame);
CRISP_API int crispGetFrameHeight(CrispFrame frame);
// Comma-separated list of roles present: "color,depth,normal,...". Owned by
// the frame, valid until the frame changes (crispReconstructFrameMotion,
// crispAttachFrameSubsamples) or is released.
CRISP_API const char* crispGetFramePasses(CrispFrame frame);
// How many colour values (channels) the file held as NaN or +-Inf; the
// "color" pass holds them sanitised (0 for NaN, clamped for Inf). An image
// with any has no error to measure: the CLI's crisp compare refuses it
// (crispCompareImages measures the sanitised values).
CRISP_API long long crispGetFrameNonFiniteColour(CrispFrame frame);
// Pointer to the pass's packed pixels (owned by the frame), or NULL with an
// error if absent. *outFormat receives its format. Valid until the frame is
// released or the pass replaced (crispReconstructFrameMotion replaces
// "motion" and "motion_flags").
CRISP_API void* crispGetFramePass(CrispFrame frame, const char* role, CrispFormat* outFormat);
// Motion vectors for a frame rendered without a Vector pass (EEVEE 3.x), from
// its "depth" pass, its "id" pass if present, and the JSON sidecars the Blender
// add-on writes: the frame's own (its path with the extension replaced by
// ".json"), previousSidecar (required) and nextSidecar (may be NULL). Adds or
// replaces the frame's "motion" pass (float4, pixels, y down: xy = previous -
// current, zw = current - next, 0 without nextSidecar; jitter removed) and a
// "motion_flags" pass (uint32 bits per pixel: 1 xy valid, 2 zw valid,
// 4 background: depth at infinity, moved by the camera's rotation alone (0
// under an orthographic camera), 8 invalid point (depth <= 0, behind the previous/next camera),
// 16 ID unknown to the sidecar (moved as static), 32 object missing from the
// previous/next sidecar); motion is 0 wherever its valid bit is clear.
// Exact for rigid object and camera motion; not for deforming meshes.
// Threads: the context's numThreads.
CRISP_API void crispReconstructFrameMotion(CrispContext context, CrispFrame frame, const char* previousSidecar,
                                           const char* nextSidecar);
// RSAA (issue 5): reads the 8 geometric sub-sample files that the frame's
// sidecar (its path with ".json") lists under "subsamples" into the frame as
// the pass "subsamples" (CRISP_FORMAT_RSAA_SUBSAMPLES records, what the rsaa
// filter reads) and passes "sub0".."sub7" (float4: world normal xyz, planar
// depth in w; the filter's other accepted form) and, when filter is not NULL, sets
// the filter's camera parameters (orthographic, proj00, proj11, proj02,
// proj12, view00..view22) from the sidecar's camera. CRISP_ERROR_INVALID_DATA
// or CRISP_ERROR_IO naming the sidecar or file: no "subsamples" list, a
// pattern other than the one the offset table was built for, a missing or
// unreadable file, another size than the frame, no Depth/Normal pass, no
// camera matrices.
CRISP_API void crispAttachFrameSubsamples(CrispContext context, CrispFrame frame, CrispFilter filter);

// Writes an image (RGB or RGBA float view, checked as crispSetFilterImage
// checks its views) to `path`; the type comes from the
// extension (.exr: float RGBA; .png: 8-bit sRGB-encoded). Writes to a
// temporary name then renames, so an existing file is never left half-written.
CRISP_API void crispWriteImage(CrispContext context, const char* path, const void* ptr,
                               CrispFormat format, size_t width, size_t height,
                               size_t pixelByteStride, size_t rowByteStride);

// The same for an .exr stored as Blender's OpenEXR output settings say:
// bitDepth 32 (float) or 16 (half: finite values beyond +-65504 are written
// as +-65504, not as infinities), compression one of none, zip, zips, piz,
// pxr24, rle, b44, b44a, dwaa, dwab (NULL: zip). crispWriteImage writes 32, zip.
CRISP_API void crispWriteImageEXR(CrispContext context, const char* path, const void* ptr,
                                  CrispFormat format, size_t width, size_t height,
                                  size_t pixelByteStride, size_t rowByteStride,
                                  int bitDepth, const char* compression);

// ---- metrics ---------------------------------------------------------------
// Figures comparing a test image with a reference, on display-encoded values
// (linear clamped to [0,1], sRGB-encoded). crispCompareImages writes the whole
// struct and the caller passes no size, so a field may be added only with a
// new CRISP_VERSION_MAJOR.
typedef struct CrispMetrics {
  double mse, rmse, psnr, snr, ssim, flip;
} CrispMetrics;

// reference/test: packed (no strides) RGB or RGBA float images of the same
// size; NaN reads as 0 and +-Inf is clamped, as a frame's colour. mask (may be
// NULL): packed float image; only pixels with mask > 0 count.
CRISP_API void crispCompareImages(CrispContext context, const void* reference, const void* test, CrispFormat format,
                                  size_t width, size_t height, const float* mask, CrispMetrics* outMetrics);

#ifdef __cplusplus
}
#endif

#endif  // CRISP_H
