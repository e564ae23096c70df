// SPDX-License-Identifier: Apache-2.0
// RSAA's compact sub-sample input: the 8 geometric sub-samples of one pixel
// (seed 003, section 4.4: depth + normal at the pattern's offsets) in one
// 80-byte record (Format::RsaaSubsamples, CRISP_FORMAT_RSAA_SUBSAMPLES).
//
//   float   depth[8]  planar depth of sample k, float32 as given (EEVEE 3.4's
//                     half-float Depth is exact in it; synthetic depths too)
//   int16_t nx[8], ny[8], nz[8]   world normal, snorm16: round(c x 32767),
//                     c clamped to [-1, 1] (encodeSnorm16); a non-finite
//                     normal is stored as (0, 0, 0) with depth NaN, which
//                     reads as background.
//
// Why this layout: the filter tests every pixel against all 8 samples, so it
// reads every byte of the record; 80 bytes is 62.5 % of the 8 float4 images
// (128 bytes). Each field is 8 values of one kind, so SIMD loads take a
// field of one pixel with one instruction, and int16 -> float is exact.
// Precision: a snorm16 component is within 1/65534 = 1.5e-5 of the input;
// the normal's direction within ~2.6e-5 rad. SADP (eq. 2.1) moves by at most
// |dn| ~ 2.6e-5 per normal, four orders below the threshold (0.2) and below
// the half-float precision of EEVEE's own Normal pass (2^-11 = 4.9e-4). Depth
// is not quantised at all: depth steps and the depth-precision slack
// (Camera::depthUlps) see exactly the values of the float4 images.
// Both the scalar reference and the SIMD path decode with the same exact
// int16 -> float conversion; the 1/32767 scale is folded into the rotation
// to view space (SubsampleDecoder), so decoding costs no extra multiply.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "core/image.h"
#include "rsaa/pattern.h"

namespace crisp::rsaa {

struct SubsampleRecord {
  float depth[kSamples];
  std::int16_t nx[kSamples], ny[kSamples], nz[kSamples];
};
static_assert(sizeof(SubsampleRecord) == 80, "the record is 80 bytes");
static_assert(sizeof(SubsampleRecord) == std::size_t(kRsaaSubsampleWords) * 4, "Format::RsaaSubsamples words");

constexpr float kSnormScale = 32767.0f;

// A normal component at snorm16 precision, as a float integer in
// [-32767, 32767]: clamped (NaN -> -1, written as the SIMD max/min
// instructions behave), scaled in float, rounded to nearest even, + 0 so
// that no -0 remains. The filter applies it to the pixel-centre normal when
// it reads records (rsaa::Kernel::centreGeo and its SIMD copy), so a flat
// face's centre and samples hold the same integers.
inline float snormCentre(float c) {
  float t = c > -1.0f ? c : -1.0f;
  t = t < 1.0f ? t : 1.0f;
  return std::nearbyint(t * kSnormScale) + 0.0f;
}

// One normal component to snorm16: the same integer as snormCentre.
inline std::int16_t encodeSnorm16(float c) { return std::int16_t(snormCentre(c)); }

// Sets sample k of a record from a depth and a world normal. Non-finite
// normals cannot be stored as snorm: such a sample gets depth NaN (which the
// SADP test treats as different from every centre, as a NaN normal was).
inline void encodeSubsample(SubsampleRecord& r, int k, float depth, float wx, float wy, float wz) {
  const bool finite = std::isfinite(wx) && std::isfinite(wy) && std::isfinite(wz);
  r.depth[k] = finite ? depth : std::nanf("");
  r.nx[k] = finite ? encodeSnorm16(wx) : 0;
  r.ny[k] = finite ? encodeSnorm16(wy) : 0;
  r.nz[k] = finite ? encodeSnorm16(wz) : 0;
}

// The record of pixel (x, y) of a Format::RsaaSubsamples view.
inline const SubsampleRecord* subsampleRecord(const ImageView& v, int x, int y) {
  return reinterpret_cast<const SubsampleRecord*>(v.pixel(x, y));
}

// A packed image of records (owned by a Frame pass or a test).
inline Image subsampleImage(int width, int height) {
  Image im(width, height, kRsaaSubsampleWords);
  im.format = Format::RsaaSubsamples;
  return im;
}

// The records of 8 float4 images of one size (sub-sample k: world normal
// xyz, planar depth in w), as attachSubsamples stores them.
inline Image packSubsamples(const Image* sub) {
  Image records = subsampleImage(sub[0].width, sub[0].height);
  auto* rec = reinterpret_cast<SubsampleRecord*>(records.data.data());
  const std::size_t n = std::size_t(sub[0].width) * std::size_t(sub[0].height);
  for (int k = 0; k < kSamples; ++k)
    for (std::size_t i = 0; i < n; ++i) {
      const float* p = sub[k].data.data() + 4 * i;
      encodeSubsample(rec[i], k, p[3], p[0], p[1], p[2]);
    }
  return records;
}

}  // namespace crisp::rsaa
