// SPDX-License-Identifier: Apache-2.0
// writeImage: RGBA EXR (float or half, in any of Blender's codecs) or 8-bit
// sRGB PNG, written through a temporary file renamed into place
// (io/temporary_file.h), so `path` holds either its old content or the whole
// new image.

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>

#include "core/color.h"
#include "core/error.h"
#include "io/frame.h"
#include "io/image_write_testing.h"
#include "io/oiio_util.h"
#include "io/temporary_file.h"

namespace crisp {

namespace {

std::function<void(const std::string&)>& faultHook() {
  static std::function<void(const std::string&)> hook;
  return hook;
}

// The largest finite half, 65504.
constexpr float kHalfMax = 65504.0f;

}  // namespace

std::string lowerExtension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

const std::vector<std::string>& exrCompressions() {
  static const std::vector<std::string> names = {"none", "zip", "zips", "piz", "pxr24",
                                                 "rle",  "b44", "b44a", "dwaa", "dwab"};
  return names;
}

void checkExrStorage(const ExrStorage& storage) {
  const auto& names = exrCompressions();
  if (std::find(names.begin(), names.end(), storage.compression) != names.end()) return;
  std::string known;
  for (const std::string& n : names) known += (known.empty() ? "" : ", ") + n;
  invalidArgument("unknown EXR compression '" + storage.compression + "' (known: " + known + ")");
}

void setWriteImageFaultForTesting(std::function<void(const std::string&)> hook) { faultHook() = std::move(hook); }

void writeImage(const std::string& path, const ImageView& image, const ExrStorage& storage) {
  FrameWindows whole;
  whole.dataWidth = image.width;
  whole.dataHeight = image.height;
  writeImage(path, image, whole, storage);
}

void writeImage(const std::string& path, const ImageView& image, const FrameWindows& windows,
                const ExrStorage& storage) {
  OiioErrorDrain drain;
  checkExrStorage(storage);
  if (path.empty()) invalidArgument("cannot write an image: the file name is empty");
  if (!image.valid()) invalidArgument("image to write to '" + path + "' is NULL");
  const int channels = image.channels();
  if (image.format == Format::UInt || (channels != 3 && channels != 4))
    invalidArgument("image to write to '" + path + "' is " + formatName(image.format) + "; expected float3 or float4");
  if (image.width <= 0 || image.height <= 0)
    invalidArgument("image to write to '" + path + "' has size " + std::to_string(image.width) + "x" +
                    std::to_string(image.height));
  // The image is the display window; the data window written is the colour's, within it.
  const OIIO::ROI display(windows.displayX, windows.displayX + image.width, windows.displayY,
                          windows.displayY + image.height);
  OIIO::ROI data = OIIO::roi_intersection(
      display, OIIO::ROI(windows.dataX, windows.dataX + windows.dataWidth, windows.dataY,
                         windows.dataY + windows.dataHeight));
  if (windows.dataWidth <= 0 || windows.dataHeight <= 0 || data.width() <= 0 || data.height() <= 0) data = display;
  const std::string ext = lowerExtension(path);
  const bool png = ext == ".png";
  if (!png && ext != ".exr")
    invalidArgument("cannot write '" + path + "': unsupported extension '" + ext + "' (use .exr or .png)");

  // Packed RGBA, converted for the file type.
  const std::size_t w = std::size_t(image.width), h = std::size_t(image.height);
  std::vector<float> rgbaFloat;
  std::vector<unsigned char> rgba8;
  if (png)
    rgba8.resize(w * h * 4);
  else
    rgbaFloat.resize(w * h * 4);
  for (int y = 0; y < image.height; ++y) {
    for (int x = 0; x < image.width; ++x) {
      const float* s = image.pixel(x, y);
      const float a = channels == 4 ? s[3] : 1.0f;
      const std::size_t o = (std::size_t(y) * w + std::size_t(x)) * 4;
      if (png) {
        // Display encoding of core/color.h; alpha is linear coverage. A PNG's
        // alpha is straight (unassociated), so the premultiplied colour is
        // divided by a partial coverage first, as Blender writes a transparent
        // film's PNG (viewers composite it as straight; an edge written
        // premultiplied shows a dark fringe). Coverage 0 keeps the colour.
        const float ac = std::isnan(a) ? 0.0f : std::clamp(a, 0.0f, 1.0f);
        const float unpremultiply = ac > 0.0f && ac < 1.0f ? 1.0f / ac : 1.0f;
        for (int k = 0; k < 3; ++k)
          rgba8[o + std::size_t(k)] = (unsigned char)std::lround(srgbEncode(s[k] * unpremultiply) * 255.0f);
        rgba8[o + 3] = (unsigned char)std::lround(ac * 255.0f);
      } else {
        for (int k = 0; k < 3; ++k) rgbaFloat[o + std::size_t(k)] = s[k];
        rgbaFloat[o + 3] = a;
        if (storage.half)  // a finite value stays finite (a half rounds 65520 and above to infinity)
          for (int k = 0; k < 4; ++k) {
            float& v = rgbaFloat[o + std::size_t(k)];
            if (std::isfinite(v)) v = std::clamp(v, -kHalfMax, kHalfMax);
          }
      }
    }
  }

  TemporaryFile tmp(path);
  std::unique_ptr<OIIO::ImageOutput> out = OIIO::ImageOutput::create(tmp.path());
  if (!out) ioError("cannot write '" + path + "': " + oiioErrors(static_cast<OIIO::ImageOutput*>(nullptr)));
  OIIO::ImageSpec spec(image.width, image.height, 4,
                       png ? OIIO::TypeDesc::UINT8 : storage.half ? OIIO::TypeDesc::HALF : OIIO::TypeDesc::FLOAT);
  if (!png) {  // a PNG holds the display window, at origin 0
    spec.set_roi_full(display);
    spec.set_roi(data);
  }
  spec.channelnames = {"R", "G", "B", "A"};
  spec.alpha_channel = 3;
  if (png) {
    spec.attribute("oiio:ColorSpace", "sRGB");
  } else {
    spec.attribute("oiio:ColorSpace", "Linear");
    spec.attribute("compression", storage.compression);
  }
  // The values above are the file's: OIIO would otherwise un-premultiply
  // colour for PNG again. The reader premultiplies a straight alpha's colour.
  spec.attribute("oiio:UnassociatedAlpha", 1);
  if (!out->open(tmp.path(), spec)) ioError("cannot write '" + path + "': " + oiioErrors(out.get()));
  // The data window's pixels, read in place from the display-window buffer by its row stride.
  const std::size_t first = (std::size_t(data.ybegin - display.ybegin) * w + std::size_t(data.xbegin - display.xbegin)) * 4;
  const bool wrote = png ? out->write_image(OIIO::TypeDesc::UINT8, rgba8.data())
                         : out->write_image(OIIO::TypeDesc::FLOAT, rgbaFloat.data() + first, OIIO::AutoStride,
                                            OIIO::stride_t(w * 4 * sizeof(float)));
  if (!wrote) {
    std::string msg = oiioErrors(out.get());
    out->close();
    ioError("cannot write '" + path + "': " + msg);
  }
  if (!out->close()) ioError("cannot write '" + path + "': " + oiioErrors(out.get()));
  out.reset();
  if (faultHook()) faultHook()(tmp.path());
  tmp.commit();
}

void writeImage(const std::string& path, const Image& image) {
  if (image.empty()) invalidArgument("image to write to '" + path + "' is empty");
  writeImage(path, image.view());
}

}  // namespace crisp
