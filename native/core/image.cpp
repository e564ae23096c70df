// SPDX-License-Identifier: Apache-2.0
#include "core/image.h"

#include <cstddef>
#include <cstdint>

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
