// SPDX-License-Identifier: Apache-2.0
#include "core/image.h"

#include <cstddef>
#include <cstdint>

#include "core/error.h"

namespace crisp {

const char* formatName(Format f) {
  switch (f) {
    case Format::Float: return "float";
    case Format::Float2: return "float2";
    case Format::Float3: return "float3";
    case Format::Float4: return "float4";
    case Format::UInt: return "uint";
    case Format::RsaaSubsamples: return "rsaa_subsamples";
    default: return "undefined";
  }
}

bool viewSpan(const ImageView& v, std::size_t& rowBytes, std::size_t& bytes) {
  return !__builtin_mul_overflow(v.pixelStride, std::size_t(v.width - 1), &rowBytes) &&
         !__builtin_add_overflow(rowBytes, formatBytes(v.format), &rowBytes) &&
         !__builtin_mul_overflow(v.rowStride, std::size_t(v.height - 1), &bytes) &&
         !__builtin_add_overflow(bytes, rowBytes, &bytes) && bytes <= std::size_t(PTRDIFF_MAX);
}

void checkViewLayout(const std::string& what, const ImageView& v) {
  if (v.width <= 0 || v.height <= 0 || v.width > kMaxDimension || v.height > kMaxDimension)
    invalidArgument(what + ": size " + std::to_string(v.width) + "x" + std::to_string(v.height) +
                    " is out of range [1, " + std::to_string(kMaxDimension) + "]");
  // A stride above PTRDIFF_MAX is a negative one passed as size_t (a bottom-up image's row stride):
  // said as the caller wrote it, not as the 2^64 - n bytes it became.
  const std::size_t kMaxStride = std::size_t(PTRDIFF_MAX);
  if (v.pixelStride > kMaxStride || v.rowStride > kMaxStride)
    invalidArgument(what + ": negative strides (pixel " + std::to_string(std::ptrdiff_t(v.pixelStride)) + ", row " +
                    std::to_string(std::ptrdiff_t(v.rowStride)) +
                    " bytes) are not supported: pass the image top row first, with positive strides");
  const std::string strides =
      "strides (pixel " + std::to_string(v.pixelStride) + ", row " + std::to_string(v.rowStride) + " bytes)";
  // Checked: a large stride would wrap the span and let pixel addresses run wild.
  std::size_t rowSpan = 0, span = 0;
  if (!viewSpan(v, rowSpan, span)) invalidArgument(what + ": " + strides + " span more memory than a process can address");
  if (v.pixelStride < formatBytes(v.format) || v.rowStride < rowSpan)
    invalidArgument(what + ": " + strides + " are smaller than the pixels they hold");
  constexpr std::size_t kAlign = alignof(float);  // = alignof(std::uint32_t)
  if (reinterpret_cast<std::uintptr_t>(v.ptr) % kAlign != 0 || v.pixelStride % kAlign != 0 || v.rowStride % kAlign != 0)
    invalidArgument(what + ": the pointer and " + strides + " must be multiples of " + std::to_string(kAlign) +
                    " bytes (values are read as 32-bit floats or integers)");
}

bool viewsOverlap(const ImageView& a, const ImageView& b) {
  std::size_t rowBytes = 0, aBytes = 0, bBytes = 0;
  if (!a.valid() || !b.valid() || !viewSpan(a, rowBytes, aBytes) || !viewSpan(b, rowBytes, bBytes)) return false;
  const char* a0 = static_cast<const char*>(a.ptr);
  const char* b0 = static_cast<const char*>(b.ptr);
  return a0 < b0 + bBytes && b0 < a0 + aBytes;
}

ImageView makeView(void* ptr, Format format, int width, int height, std::size_t pixelStride, std::size_t rowStride) {
  ImageView v;
  v.ptr = ptr;
  v.format = format;
  v.width = width;
  v.height = height;
  v.pixelStride = pixelStride ? pixelStride : formatBytes(format);
  v.rowStride = rowStride ? rowStride : v.pixelStride * std::size_t(width);
  return v;
}

Image::Image(int w, int h, int c, float fill)
    : width(w), height(h), channels(c), format(Format(c)), data(std::size_t(w) * std::size_t(h) * std::size_t(c), fill) {}

Image Image::uintImage(int w, int h) {
  Image im(w, h, 1, 0.0f);  // all-zero bits = ID 0
  im.format = Format::UInt;
  return im;
}

ImageView Image::view() const {
  return makeView(const_cast<float*>(data.data()), format, width, height);
}

}  // namespace crisp
