// SPDX-License-Identifier: Apache-2.0
// TAA baseline (seed 000 chapter III): the GLSL twin of native/filters/taa.cpp
// (taa.h) and the temporal helpers it uses (native/temporal/*.h). Same
// function names, parameter names and defaults; the steps and their sources
// are described in taa.cpp's header.
//
// Passes (gpu_filters.py; both declare every sampler and push constant of
// this file, and exactly one pass macro):
//  1. TAA_RESOLVE_PASS  colorImage (this frame, 1 jittered sample per pixel),
//                       historyImage (the previous history, RGBA32F, colour in
//                       the clip space + signed sample weight), motionImage
//                       (optional, hasMotion; pixels, previous - current, the
//                       texture's y), markImage (RGBA32F: r = taa.cpp's
//                       historyState of that history, feedbackSinceReset
//                       (0/1) + 2 x framesSinceReset; gba = the pixel's
//                       Kernel::holdWindows_ word, stepHoldWindow below)
//                       -> out vec4 historyOut (location 0),
//                       out vec4 fragColor (location 1, the output unless sharpening),
//                       out vec4 markOut (location 2, the mark of historyOut)
//     = taa.cpp referencePixel + taa_rows.h resolveLanes without depth and
//       aliasedValue;
//  2. TAA_SHARPEN_PASS  historyImage (the history just written), colorImage
//                       (alpha) -> out vec4 fragColor = taa.cpp sharpenPixel<true>.
// History and mark ping-pong between two texture pairs kept by gpu_filters.py
// between redraws (the C++ Kernel's history_[2]; its historyState_ plane
// is updated in place there); hasHistory = 0 is Kernel::reset().
//
// Parameters (taa.cpp table; enum-valued ones as ints):
//   jitterX 0, jitterY 0 (pixels, the texture's x and y),
//   jitterWeighting 0 = none / 1 = blackman-harris, filterSize 1.5,
//   historyFilter 0 = catmull-rom / 1 = bilinear, clipSpace 0 = ycocg / 1 = rgb,
//   feedbackMin 0.7, feedbackMax 0.85, sharpen 0, staticAccumulation 1,
//   maxSamples 128, holdPeriod 16, holdRelease 0.002 (as holdLimit, below), varianceClip 1, resampleDamping 0.3, staticClip 1,
//   unjitter 0 = none / 1 = nearest / 2 = blackman-harris (default 2). (depthTolerance: no depth here.)
// Per frame, from gpu_filters.py: hasHistory, hasMotion, holdWindowEnd (this
// frame closes a window of holdPeriod frames: temporal::holdWindowEnds of the
// frames since reset), holdWindowsFresh (the windows restart: a new holdPeriod),
// holdLimit (temporal::holdWindowLimit of holdRelease, computed in float32 there).
//
// Not in this version, on purpose: depth (closest-depth velocity and the
// disocclusion test) and the aliasedValue plane of taa-improved. The viewport
// offers neither a depth pass nor motion vectors (BLENDER.md, README "Sources":
// EEVEE's buffers are not accessible), so the preview runs the static path (motion 0, history
// reset whenever the view changes); motion is still accepted for tests.
//
// Known differences from the C++ kernel (besides common.glsl's):
//  * blackmanHarrisWeight is evaluated in float (C++: double, then rounded);
//  * holdLumaOfLinear divides with the GPU's division (GLSL allows 2.5 ulp),
//    and the compiler may contract its multiply-add and lumaOf into FMAs
//    (C++: -ffp-contract=off; GLSL 3.30 has no `precise`), so a luminance
//    within an ulp of a quantisation step may land one step off: a window's
//    sum then differs by one from the C++ one;
//  * a moving pixel's Catmull-Rom/bilinear fetch is explicit texelFetch taps
//    with the C++ summation order (not the sampler's filtering).

const float kClipEpsilon = 1e-7;  // temporal/neighbourhood.h

// ---- temporal/color_space.h -----------------------------------------------
vec3 rgbToYCoCg(vec3 c) {
  return vec3(0.25 * c.r + 0.5 * c.g + 0.25 * c.b, 0.5 * c.r - 0.5 * c.b, -0.25 * c.r + 0.5 * c.g - 0.25 * c.b);
}
vec3 yCoCgToRgb(vec3 c) { return vec3(c.x + c.y - c.z, c.x + c.z, c.x - c.y - c.z); }

// ---- temporal/jitter.cpp blackmanHarrisWindow / blackmanHarrisWeight ------
float blackmanHarrisWindow(float t) {
  if (t <= 0.0 || t >= 1.0) return 0.0;
  float a = 2.0 * 3.14159265358979 * t;
  return 0.35875 - 0.48829 * cos(a) + 0.14128 * cos(2.0 * a) - 0.01168 * cos(3.0 * a);
}
float blackmanHarrisWeight(float x, float y, float filterSize) {
  if (!(filterSize > 0.0)) return 1.0;
  float width = 2.0 * filterSize;  // the window spans [-filterSize, filterSize]
  float tx = x / width + 0.5, ty = y / width + 0.5;
  return blackmanHarrisWindow(tx) * blackmanHarrisWindow(ty) / (0.35875 * 0.35875);
}

// ---- taa_rows.h stagePixel / lumaOf / toRgb --------------------------------
vec4 stagePixel(vec4 p, int space) {
  vec3 rgb = vec3(sanitizeColor(p.r), sanitizeColor(p.g), sanitizeColor(p.b));
  vec3 c = space == 0 ? rgbToYCoCg(rgb) : rgb;
  return vec4(c, sanitizeColor(p.a));
}
float lumaOf(vec4 c, int space) { return space == 0 ? c.x : 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }
vec3 toRgb(vec3 c, int space) { return space == 0 ? yCoCgToRgb(c) : c; }

// C++ vmin/vmax operand order (temporal/vec4.h).
vec4 vmin(vec4 a, vec4 b) { return mix(a, b, lessThan(b, a)); }
vec4 vmax(vec4 a, vec4 b) { return mix(a, b, lessThan(a, b)); }

// ---- temporal/neighbourhood.h columnFirstBoxes4 ----------------------------
struct MinMax4 {
  vec4 lo, hi;
};
void columnFirstBoxes4(vec4 taps[9], out MinMax4 box3x3, out MinMax4 cross) {
  vec4 lmin = vmin(vmin(taps[0], taps[3]), taps[6]), lmax = vmax(vmax(taps[0], taps[3]), taps[6]);
  vec4 cmin = vmin(vmin(taps[1], taps[4]), taps[7]), cmax = vmax(vmax(taps[1], taps[4]), taps[7]);
  vec4 rmin = vmin(vmin(taps[2], taps[5]), taps[8]), rmax = vmax(vmax(taps[2], taps[5]), taps[8]);
  box3x3 = MinMax4(vmin(vmin(lmin, cmin), rmin), vmax(vmax(lmax, cmax), rmax));
  cross = MinMax4(vmin(vmin(taps[3], cmin), taps[5]), vmax(vmax(taps[3], cmax), taps[5]));
}

// ---- temporal/neighbourhood.h TwoExtremes4 ---------------------------------
struct TwoExtremes4 {
  vec4 max1, max2, min1, min2;
};
TwoExtremes4 twoExtremesOf(vec4 a, vec4 b) { return TwoExtremes4(vmax(a, b), vmin(a, b), vmin(a, b), vmax(a, b)); }
void addTap(inout TwoExtremes4 e, vec4 v) {
  e.max2 = vmax(e.max2, vmin(e.max1, v));
  e.max1 = vmax(e.max1, v);
  e.min2 = vmin(e.min2, vmax(e.min1, v));
  e.min1 = vmin(e.min1, v);
}

// ---- temporal/neighbourhood.h clipTowardCentre4 ----------------------------
vec4 clipTowardCentre4(vec4 p, vec4 lo, vec4 hi, out float excess) {
  vec4 centre = 0.5 * (hi + lo);
  vec4 halfExtent = 0.5 * (hi - lo) + kClipEpsilon;
  vec4 offset = p - centre;
  vec4 ratio = abs(offset) / halfExtent;
  float e = max(max(ratio.x, ratio.y), ratio.z);
  excess = e;
  if (!(e > 1.0)) return p;
  vec4 clipped = centre + offset * (1.0 / e);
  clipped.w = p.w;
  return clipped;
}

// ---- temporal/history_fetch.h ----------------------------------------------
bool onScreen(float x, float y, int width, int height) {
  return x >= -0.5 && y >= -0.5 && x <= float(width) - 0.5 && y <= float(height) - 0.5;
}
vec4 historyAt(int x, int y) { return fetchClamped(historyImage, x, y); }

vec4 fetchBilinear4(float x, float y) {
  float fx = floor(x), fy = floor(y);
  float tx = x - fx, ty = y - fy;
  int x0 = int(fx), y0 = int(fy);
  vec4 p00 = historyAt(x0, y0), p10 = historyAt(x0 + 1, y0);
  vec4 p01 = historyAt(x0, y0 + 1), p11 = historyAt(x0 + 1, y0 + 1);
  vec4 top = p00 + (p10 - p00) * tx;
  vec4 bottom = p01 + (p11 - p01) * tx;
  vec4 result = top + (bottom - top) * ty;
  result.w = historyAt(tx < 0.5 ? x0 : x0 + 1, ty < 0.5 ? y0 : y0 + 1).w;
  return result;
}

vec4 catmullRomWeights(float t) {
  return vec4(t * (-0.5 + t * (1.0 - 0.5 * t)), 1.0 + t * t * (-2.5 + 1.5 * t), t * (0.5 + t * (2.0 - 1.5 * t)),
              t * t * (-0.5 + 0.5 * t));
}

vec4 fetchCatmullRom4(float x, float y) {
  float fx = floor(x), fy = floor(y);
  float tx = x - fx, ty = y - fy;
  int x0 = int(fx), y0 = int(fy);
  vec4 wx = catmullRomWeights(tx), wy = catmullRomWeights(ty);
  vec4 acc = vec4(0.0), lo = vec4(0.0), hi = vec4(0.0);
  for (int j = 0; j < 4; ++j) {
    int row = y0 - 1 + j;
    vec4 t0 = historyAt(x0 - 1, row), t1 = historyAt(x0, row), t2 = historyAt(x0 + 1, row), t3 = historyAt(x0 + 2, row);
    vec4 r = ((t0 * wx[0] + t1 * wx[1]) + t2 * wx[2]) + t3 * wx[3];
    acc += r * wy[j];
    if (j == 1) {
      lo = vmin(t1, t2);
      hi = vmax(t1, t2);
    } else if (j == 2) {
      lo = vmin(lo, vmin(t1, t2));
      hi = vmax(hi, vmax(t1, t2));
    }
  }
  vec4 result = vmin(vmax(acc, lo), hi);
  result.w = historyAt(tx < 0.5 ? x0 : x0 + 1, ty < 0.5 ? y0 : y0 + 1).w;
  return result;
}

// temporal/velocity.h finiteMotion.
bool finiteMotion(float mx, float my) { return finiteValue(mx) && finiteValue(my); }

// temporal/jitter.h shiftedSource: the input index tap q of the shifted image reads.
int shiftedSource(int q, int size, int shift) { return clampIndex(clampIndex(q, size) - shift, size); }

// temporal/jitter.cpp unjitterFor: the shift (std::lround: halves away from zero, clamped
// to +-2) and the normalised 3x3 weights of this frame's jitter.
int unjitterShift(float j) {
  if (unjitter == 0) return 0;
  int s = int(sign(j) * floor(abs(j) + 0.5));
  return s < -2 ? -2 : (s > 2 ? 2 : s);
}
void unjitterWeights(int sx, int sy, out float weights[9]) {
  float dx = jitterX - float(sx), dy = jitterY - float(sy);
  float sum = 0.0;
  for (int i = 0; i < 9; ++i) {
    weights[i] = unjitter == 2 ? blackmanHarrisWeight(float(i % 3 - 1) + dx, float(i / 3 - 1) + dy, filterSize) : 0.0;
    sum += weights[i];
  }
  if (!(sum > 0.0)) {
    for (int i = 0; i < 9; ++i) weights[i] = 0.0;
    weights[4] = 1.0;
    sum = 1.0;
  }
  for (int i = 0; i < 9; ++i) weights[i] /= sum;
}

// ---- temporal/hold_release.h (the release of held still pixels) -----------
// The C++ word's fields as exact integers in floats: x = the running window's
// sum (+ 32768 while it has none), y = the baseline (32767: none), z = pending.
const vec3 kHoldWindowNone = vec3(32768.0, 32767.0, 0.0);
float holdLumaOfLinear(float luminance) {
  float y = luminance < 0.0 ? 0.0 : luminance;
  float t = (1.0 - 1.0 / (1.0 + y)) * 255.0 + 0.5;
  return (t > 0.0 && t < 256.0) ? floor(t) : 0.0;
}
vec3 holdWindowRestarted(bool windowEnd) { return windowEnd ? vec3(0.0, 32767.0, 0.0) : kHoldWindowNone; }
vec3 stepHoldWindow(vec3 word, float luma, bool still, bool windowEnd, float limit,
                    out bool released) {
  float sum = word.x + luma, baseline = word.y;
  bool pending = word.z > 0.0;
  released = false;
  if (windowEnd) {
    bool hasSum = sum < 32768.0;
    bool complete = hasSum && baseline != 32767.0;
    float diff = sum - baseline;
    bool differs = complete && (diff > limit || diff < -limit);
    released = still && differs && pending;
    bool wait = still && differs && !pending;
    baseline = wait ? baseline : (hasSum ? sum : 32767.0);
    pending = wait;
    sum = 0.0;
  }
  if (!still || released) return holdWindowRestarted(windowEnd);
  return vec3(sum, baseline, pending ? 1.0 : 0.0);
}

#ifdef TAA_RESOLVE_PASS
// taa.cpp footprintBox of the reference path: the 3x3 box united with the 5x5
// box of second-largest / second-smallest values (clamped taps, row order).
vec4 shiftedTap(int x, int y, int sx, int sy, int space) {
  ivec2 size = textureSize(colorImage, 0);
  return stagePixel(texelFetch(colorImage, ivec2(shiftedSource(x, size.x, sx), shiftedSource(y, size.y, sy)), 0), space);
}
MinMax4 footprintBox(MinMax4 box3x3, int x, int y, int sx, int sy, int space) {
  TwoExtremes4 e = twoExtremesOf(shiftedTap(x - 2, y - 2, sx, sy, space), shiftedTap(x - 1, y - 2, sx, sy, space));
  for (int i = 2; i < 25; ++i) addTap(e, shiftedTap(x + i % 5 - 2, y + i / 5 - 2, sx, sy, space));
  return MinMax4(vmin(box3x3.lo, e.min2), vmax(box3x3.hi, e.max2));
}

// temporal/velocity.h stillFootprint: nothing in the (shifted) 5x5 moves.
bool stillFootprint(int x, int y, int sx, int sy) {
  if (hasMotion == 0) return true;
  ivec2 size = textureSize(motionImage, 0);
  for (int i = 0; i < 25; ++i) {
    vec4 m = texelFetch(motionImage, ivec2(shiftedSource(x + i % 5 - 2, size.x, sx),
                                           shiftedSource(y + i / 5 - 2, size.y, sy)), 0);
    if (m.x != 0.0 || m.y != 0.0) return false;
  }
  return true;
}

// taa.cpp referencePixel + taa_rows.h resolveLanes (no depth, no aliasedValue).
void taaResolvePass() {
  ivec2 p = fragmentPixel();
  int x = p.x, y = p.y;
  ivec2 size = textureSize(colorImage, 0);
  int w = size.x, h = size.y;
  int sx = unjitterShift(jitterX), sy = unjitterShift(jitterY);
  vec4 taps[9];
  for (int i = 0; i < 9; ++i) taps[i] = shiftedTap(x + i % 3 - 1, y + i / 3 - 1, sx, sy, clipSpace);
  MinMax4 box3x3, cross;
  columnFirstBoxes4(taps, box3x3, cross);
  vec4 current = taps[4];  // taa.cpp: the unjittered mix, or the centre tap without unjitter
  if (unjitter != 0) {
    float uw[9];
    unjitterWeights(sx, sy, uw);
    current = taps[4] * uw[4];
    for (int i = 0; i < 9; ++i)
      if (i != 4) current = current + taps[i] * uw[i];
  }
  float alpha = sanitizeColor(texelFetch(colorImage, p, 0).a);  // taa_rows.h alphaOf: the input's, passed through

  // Step 3: velocity of the centre's tap (no depth to follow).
  float vx = 0.0, vy = 0.0;
  if (hasMotion != 0) {
    vec4 m = texelFetch(motionImage, ivec2(shiftedSource(x, w, sx), shiftedSource(y, h, sy)), 0);
    vx = m.x;
    vy = m.y;
  }
  bool moving = vx != 0.0 || vy != 0.0;

  // Step 8: usable history at p + v?
  float qx = float(x) + vx, qy = float(y) + vy;
  bool valid = hasHistory != 0 && finiteMotion(vx, vy) && onScreen(qx, qy, w, h);
  vec4 hist = vec4(0.0);
  if (valid) {
    if (!moving)
      hist = texelFetch(historyImage, p, 0);
    else if (historyFilter == 0)
      hist = fetchCatmullRom4(qx, qy);
    else
      hist = fetchBilinear4(qx, qy);
  }
  float historyWeight = valid ? abs(hist.w) : 0.0;
  float weight = jitterWeighting == 1 ? blackmanHarrisWeight(jitterX, jitterY, filterSize) : 1.0;
  float weightSum = historyWeight + weight;

  vec4 result = current;
  float newWeight = weight;
  bool reset = !valid || !(weightSum > 0.0);
  vec4 marks = texelFetch(markImage, p, 0);
  float state = marks.r;  // historyState
  bool averaging = false;  // a still pixel that averaged (held or not), for the hold's release
  float framesSinceReset = floor(state / 2.0);
  float mark = state - 2.0 * framesSinceReset;  // feedbackSinceReset
  if (!reset) {
    bool staticPixel = staticAccumulation != 0 && !moving && hist.w > 0.0;
    float excess = 0.0;
    if (staticPixel && staticClip != 0) {
      clipTowardCentre4(hist, box3x3.lo, box3x3.hi, excess);
      if (excess > 1.0 && !(mark > 0.0) && stillFootprint(x, y, sx, sy)) {
        MinMax4 box = footprintBox(box3x3, x, y, sx, sy, clipSpace);
        clipTowardCentre4(hist, box.lo, box.hi, excess);
      }
    }
    averaging = staticPixel && (staticClip == 0 || !(excess > 1.0));
    if (averaging) {
      if (holdPeriod > 0 && !(mark > 0.0) && framesSinceReset >= float(holdPeriod)) {
        result = hist;  // taa.cpp "Hold"
        newWeight = historyWeight;
      } else {
        result = hist + (current - hist) * (weight / weightSum);
        newWeight = min(weightSum, float(max(1, maxSamples)));
      }
    } else {
      mark = 1.0;  // kept until a reset
      vec4 lo = 0.5 * (box3x3.lo + cross.lo);
      vec4 hi = 0.5 * (box3x3.hi + cross.hi);
      if (varianceClip > 0.0) {  // taa_rows.h momentsOf: mean +- gamma sigma, clamped into the box
        vec4 sum = taps[0], squares = taps[0] * taps[0];
        for (int i = 1; i < 9; ++i) {
          sum = sum + taps[i];
          squares = squares + taps[i] * taps[i];
        }
        vec4 mean = sum * (1.0 / 9.0);
        vec4 sigma = sqrt(max(squares * (1.0 / 9.0) - mean * mean, vec4(0.0)));
        vec4 boxLo = lo, boxHi = hi;
        lo = clamp(mean - varianceClip * sigma, boxLo, boxHi);
        hi = clamp(mean + varianceClip * sigma, boxLo, boxHi);
      }
      vec4 clipped = clipTowardCentre4(hist, lo, hi, excess);
      float l0 = lumaOf(clipped, clipSpace), l1 = lumaOf(current, clipSpace);
      float diff = clamp(abs(l0 - l1) / max(max(l0, l1), 0.2), 0.0, 1.0);
      float unbiased = (1.0 - diff) * (1.0 - diff);
      float k = feedbackMin + (feedbackMax - feedbackMin) * unbiased;
      if (resampleDamping > 0.0) {  // taa.cpp "Deliberate choices"
        float tx = qx - floor(qx), ty = qy - floor(qy);
        k = k * (1.0 - resampleDamping * max(4.0 * tx * (1.0 - tx), 4.0 * ty * (1.0 - ty)));
      }
      float mixWeight = max(1.0 - k, weight / weightSum);
      result = clipped + (current - clipped) * mixWeight;
      newWeight = 1.0 - k > 0.0 ? min(weightSum, 1.0 / (1.0 - k)) : weightSum;
      newWeight = min(newWeight, float(max(1, maxSamples)));
    }
    reset = !(finiteValue(result.x) && finiteValue(result.y) && finiteValue(result.z));  // never a non-finite history
  }
  // taa.cpp "Hold": a still averaging pixel whose input changed for two
  // windows running restarts, as at a reset.
  vec3 windows = kHoldWindowNone;
  if (holdPeriod > 0) {
    bool released;
    windows = stepHoldWindow(holdWindowsFresh != 0 ? kHoldWindowNone : marks.gba,
                             holdLumaOfLinear(lumaOf(current, clipSpace)), averaging, holdWindowEnd != 0,
                             float(holdLimit), released);
    reset = reset || released;
  }
  framesSinceReset = min(framesSinceReset + 1.0, 127.0);
  if (reset) {
    result = current;
    newWeight = weight;
    mark = 0.0;
    framesSinceReset = 1.0;
  }
  result.w = moving ? -newWeight : newWeight;
  historyOut = result;
  markOut = vec4(mark + 2.0 * framesSinceReset, windows);
  if (reset && unjitter == 0) {
    vec4 c = sanitizeColor4(texelFetch(colorImage, p, 0));  // the input itself, not its YCoCg round trip
    fragColor = vec4(c.rgb, alpha);
  } else {
    vec3 rgb = toRgb(result.xyz, clipSpace);
    fragColor = vec4(sanitizeColor(rgb.r), sanitizeColor(rgb.g), sanitizeColor(rgb.b), alpha);
  }
}
#endif

#ifdef TAA_SHARPEN_PASS
// taa.cpp sharpenPixel<true> (eq. 3.1), from the history just written.
void taaSharpenPass() {
  ivec2 p = fragmentPixel();
  vec4 c = historyAt(p.x, p.y);
  vec4 n[4] = vec4[4](historyAt(p.x, p.y - 1), historyAt(p.x - 1, p.y), historyAt(p.x + 1, p.y), historyAt(p.x, p.y + 1));
  vec3 result;
  for (int ch = 0; ch < 3; ++ch) {
    float lo = c[ch], hi = c[ch];
    float sum = 0.0;
    for (int i = 0; i < 4; ++i) {
      sum += n[i][ch];
      lo = min(lo, n[i][ch]);
      hi = max(hi, n[i][ch]);
    }
    float sharpened = c[ch] + sharpen * (4.0 * c[ch] - sum);
    result[ch] = clamp(sharpened, lo, hi);
  }
  vec3 rgb = toRgb(result, clipSpace);
  float alpha = sanitizeColor(texelFetch(colorImage, p, 0).a);
  fragColor = vec4(sanitizeColor(rgb.r), sanitizeColor(rgb.g), sanitizeColor(rgb.b), alpha);
}
#endif
