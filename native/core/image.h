// SPDX-License-Identifier: Apache-2.0
// Image views (non-owning, strided) and owned images. See conventions.h.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace crisp {

// RsaaSubsamples: RSAA's packed 80-byte sub-sample record per pixel (rsaa/subsample_record.h);
// counted as 20 four-byte words so strides and role checks work unchanged.
enum class Format : int { Undefined = 0, Float = 1, Float2 = 2, Float3 = 3, Float4 = 4, UInt = 5, RsaaSubsamples = 6 };
inline constexpr int kRsaaSubsampleWords = 20;

inline int formatChannels(Format f) {
  switch (f) {
    case Format::Float: return 1;
    case Format::Float2: return 2;
    case Format::Float3: return 3;
    case Format::Float4: return 4;
    case Format::UInt: return 1;
    case Format::RsaaSubsamples: return kRsaaSubsampleWords;
    default: return 0;
  }
}
inline std::size_t formatBytes(Format f) { return std::size_t(formatChannels(f)) * 4; }
const char* formatName(Format f);

// A non-owning strided view, as handed in through the C API.
struct ImageView {
  void* ptr = nullptr;
  Format format = Format::Undefined;
  int width = 0;
  int height = 0;
  std::size_t pixelStride = 0;  // bytes
  std::size_t rowStride = 0;    // bytes

  bool valid() const { return ptr != nullptr; }
  int channels() const { return formatChannels(format); }
  float* row(int y) const { return reinterpret_cast<float*>(static_cast<char*>(ptr) + std::size_t(y) * rowStride); }
  float* pixel(int x, int y) const {
    return reinterpret_cast<float*>(static_cast<char*>(ptr) + std::size_t(y) * rowStride + std::size_t(x) * pixelStride);
  }
  std::uint32_t uintAt(int x, int y) const {
    std::uint32_t v;
    std::memcpy(&v, pixel(x, y), 4);
    return v;
  }
  bool packed() const { return pixelStride == formatBytes(format) && rowStride == pixelStride * std::size_t(width); }
};

// The largest width or height of an image the library takes (the C API's limit).
constexpr int kMaxDimension = 1 << 16;

// The bytes a view addresses from its first pixel: one row's (rowBytes) and the whole view's
// (bytes). False when they overflow what a process can address (a stride near SIZE_MAX).
bool viewSpan(const ImageView& v, std::size_t& rowBytes, std::size_t& bytes);
// Throws InvalidArgument, naming `what` ("image 'color'"), unless the view's size is in [1,
// kMaxDimension], its strides hold its pixels without wrapping the address space, and its pointer
// and strides are multiples of 4 bytes (its values are read as floats or uint32). Every view the C
// API is given passes here.
void checkViewLayout(const std::string& what, const ImageView& v);
// True if the bytes two views address may overlap (an output given an input's buffer).
bool viewsOverlap(const ImageView& a, const ImageView& b);

// Fills in packed strides where 0 was given.
ImageView makeView(void* ptr, Format format, int width, int height, std::size_t pixelStride = 0,
                   std::size_t rowStride = 0);

// An owned, packed, interleaved float image with 1..4 channels (or uint32 IDs
// stored bit-for-bit in the float storage, Format::UInt).
struct Image {
  int width = 0;
  int height = 0;
  int channels = 0;
  Format format = Format::Undefined;
  std::vector<float> data;

  Image() = default;
  Image(int w, int h, int c, float fill = 0.0f);
  static Image uintImage(int w, int h);

  bool empty() const { return data.empty(); }
  std::size_t index(int x, int y) const { return (std::size_t(y) * std::size_t(width) + std::size_t(x)) * std::size_t(channels); }
  float* at(int x, int y) { return data.data() + index(x, y); }
  const float* at(int x, int y) const { return data.data() + index(x, y); }
  std::uint32_t uintAt(int x, int y) const {
    std::uint32_t v;
    std::memcpy(&v, at(x, y), 4);
    return v;
  }
  void setUint(int x, int y, std::uint32_t v) { std::memcpy(at(x, y), &v, 4); }
  ImageView view() const;
};

}  // namespace crisp
