// SPDX-License-Identifier: Apache-2.0
#include "core/image.h"

#include <utility>

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

bool viewsOverlap(const ImageView& a, const ImageView& b) {
  auto span = [](const ImageView& v) {
    const char* p = static_cast<const char*>(v.ptr);
    return std::make_pair(p, p + std::size_t(v.height - 1) * v.rowStride + std::size_t(v.width - 1) * v.pixelStride +
                                 formatBytes(v.format));
  };
  auto [a0, a1] = span(a);
  auto [b0, b1] = span(b);
  return a.valid() && b.valid() && a0 < b1 && b0 < a1;
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
