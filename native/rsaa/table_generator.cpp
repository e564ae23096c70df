// SPDX-License-Identifier: Apache-2.0
// The RSAA offset-table generator; the model is described in
// table_generator.h (seed 003, section 2.3.2).
#include "rsaa/table_generator.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <sstream>

#include "core/error.h"

namespace crisp::rsaa {

const char* offsetSourceName(OffsetSource s) {
  switch (s) {
    case OffsetSource::OneLine: return "one-line";
    case OffsetSource::TwoLines: return "two-lines";
    case OffsetSource::Fallback: return "fallback";
    case OffsetSource::Centre: return "centre";
  }
  return "?";
}

namespace {

struct Line {
  double nx, ny, c;  // the centre's side is nx x + ny y < c
};

// Uniform double in [0, 1) from two raw mt19937 outputs (53 bits).
double uniform01(std::mt19937& g) {
  const double hi = double(g() >> 5);  // 27 bits
  const double lo = double(g() >> 6);  // 26 bits
  return (hi * 67108864.0 + lo) * (1.0 / 9007199254740992.0);
}

// A random line that may reach the pixel: uniform direction, distance from
// the centre uniform in (0, sqrt(1/2)].
Line randomLine(std::mt19937& g) {
  double x, y, s;
  do {
    x = 2.0 * uniform01(g) - 1.0;
    y = 2.0 * uniform01(g) - 1.0;
    s = x * x + y * y;
  } while (s > 1.0 || s < 1e-6);
  const double len = std::sqrt(s);
  double c;
  do {
    c = uniform01(g) * std::sqrt(0.5);
  } while (c <= 0.0);  // the centre must lie strictly on one side
  return {x / len, y / len, c};
}

bool inside(const Line* lines, int n, double x, double y) {
  for (int i = 0; i < n; ++i)
    if (!(lines[i].nx * x + lines[i].ny * y < lines[i].c)) return false;
  return true;
}

// Area of the pixel square [-0.5, 0.5]^2 on the centre's side of every line
// (Sutherland-Hodgman clipping, shoelace area).
double areaA(const Line* lines, int n) {
  std::array<double, 16> px{}, py{}, qx{}, qy{};
  int count = 4;
  px[0] = -0.5, py[0] = -0.5;
  px[1] = 0.5, py[1] = -0.5;
  px[2] = 0.5, py[2] = 0.5;
  px[3] = -0.5, py[3] = 0.5;
  for (int l = 0; l < n && count > 0; ++l) {
    const Line& L = lines[l];
    int out = 0;
    for (int i = 0; i < count; ++i) {
      const int j = (i + 1) % count;
      const double si = L.nx * px[i] + L.ny * py[i] - L.c;
      const double sj = L.nx * px[j] + L.ny * py[j] - L.c;
      if (si <= 0.0) qx[out] = px[i], qy[out] = py[i], ++out;
      if ((si < 0.0 && sj > 0.0) || (si > 0.0 && sj < 0.0)) {
        const double t = si / (si - sj);  // si != sj here
        qx[out] = px[i] + t * (px[j] - px[i]);
        qy[out] = py[i] + t * (py[j] - py[i]);
        ++out;
      }
    }
    count = out;
    px = qx;
    py = qy;
  }
  double twice = 0.0;
  for (int i = 0; i < count; ++i) {
    const int j = (i + 1) % count;
    twice += px[i] * py[j] - px[j] * py[i];
  }
  return std::fabs(0.5 * twice);
}

// Sum over configurations of v v^T, v = (-cov_B, Bx, By, Bxy - Bx - By):
// the error of offset (a, b) in this quadrant is m^T M m, m = (1, a, b, ab).
struct Quadric {
  double m[4][4] = {};
  void add(const double v[4]) {
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) m[i][j] += v[i] * v[j];
  }
  double eval(double a, double b) const {
    const double u[4] = {1.0, a, b, a * b};
    double e = 0.0;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) e += u[i] * m[i][j] * u[j];
    return e;
  }
  // Exact minimiser over t in [0, 1] of m^T M m with m = p + t q.
  double minimiseLine(const double p[4], const double q[4]) const {
    double pq = 0.0, qq = 0.0;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) {
        pq += p[i] * m[i][j] * q[j];
        qq += q[i] * m[i][j] * q[j];
      }
    if (qq > 0.0) return std::min(1.0, std::max(0.0, -pq / qq));
    return pq < 0.0 ? 1.0 : 0.0;  // concave or flat: an end point
  }
  double bestA(double b) const {  // m = (1, 0, b, 0) + a (0, 1, 0, b)
    const double p[4] = {1.0, 0.0, b, 0.0}, q[4] = {0.0, 1.0, 0.0, b};
    return minimiseLine(p, q);
  }
  double bestB(double a) const {  // m = (1, a, 0, 0) + b (0, 0, 1, a)
    const double p[4] = {1.0, a, 0.0, 0.0}, q[4] = {0.0, 0.0, 1.0, a};
    return minimiseLine(p, q);
  }
};

struct Family {
  Quadric quadrant[kMasks][4];  // quadrant q: sx = q & 1 ? -1 : 1, sy = q & 2 ? -1 : 1
  long count[kMasks] = {};
  double coverageB[kMasks] = {};
};

void accumulate(const Line* lines, int n, const Pattern& pattern, Family& family) {
  int mask = 0;
  for (int k = 0; k < kSamples; ++k)
    if (inside(lines, n, double(pattern.x[k]), double(pattern.y[k]))) mask |= 1 << k;
  const double covB = std::min(1.0, std::max(0.0, 1.0 - areaA(lines, n)));
  family.count[mask] += 1;
  family.coverageB[mask] += covB;
  for (int q = 0; q < 4; ++q) {
    const double sx = (q & 1) ? -1.0 : 1.0, sy = (q & 2) ? -1.0 : 1.0;
    const double bx = inside(lines, n, sx, 0.0) ? 0.0 : 1.0;
    const double by = inside(lines, n, 0.0, sy) ? 0.0 : 1.0;
    const double bxy = inside(lines, n, sx, sy) ? 0.0 : 1.0;
    const double v[4] = {-covB, bx, by, bxy - bx - by};
    family.quadrant[mask][q].add(v);
  }
}

struct Fit {
  double a = 0, b = 0, error = 0;
};

Fit minimise(const Quadric& Q) {
  constexpr int kScan = 4096;
  Fit best;
  best.error = HUGE_VAL;
  for (int i = 0; i <= kScan; ++i) {
    const double b = double(i) / kScan;
    const double a = Q.bestA(b);
    const double e = Q.eval(a, b);
    if (e < best.error) best = {a, b, e};
  }
  for (int it = 0; it < 64; ++it) {
    const double a = Q.bestA(best.b);
    const double b = Q.bestB(a);
    const double e = Q.eval(a, b);
    if (!(e < best.error)) break;
    best = {a, b, e};
  }
  return best;
}

}  // namespace

GeneratedTable generateOffsetTable(const GeneratorOptions& options) {
  if (options.configurations <= 0)
    invalidArgument("rsaa table generator: configurations = " + std::to_string(options.configurations) +
                    " must be positive");
  for (int k = 0; k < kSamples; ++k) {
    const float x = options.pattern.x[k], y = options.pattern.y[k];
    if (!(std::fabs(x) < 0.5f) || !(std::fabs(y) < 0.5f))
      invalidArgument("rsaa table generator: pattern point " + std::to_string(k) +
                      " must lie strictly inside the pixel (|x|, |y| < 0.5)");
  }
  GeneratedTable table;
  table.options = options;
  auto one = std::make_unique<Family>();
  auto two = std::make_unique<Family>();
  std::mt19937 g(options.seed);
  for (long i = 0; i < options.configurations; ++i) {
    Line l[2];
    l[0] = randomLine(g);
    accumulate(l, 1, options.pattern, *one);
    l[0] = randomLine(g);
    l[1] = randomLine(g);
    accumulate(l, 2, options.pattern, *two);
  }
  for (int mask = 0; mask < kMasks; ++mask) {
    if (mask == kMasks - 1) {  // every sample on the centre's polygon: keep the centre
      table.source[mask] = OffsetSource::Centre;
      continue;
    }
    const Family* f = one->count[mask] > 0 ? one.get() : two->count[mask] > 0 ? two.get() : nullptr;
    if (!f) {
      // Neither family produces the mask (2.3.2, last sentence): towards the
      // farthest B sample, length = fraction of B samples.
      int farthest = -1, numB = 0;
      float farD2 = -1.0f;
      for (int k = 0; k < kSamples; ++k) {
        if (mask & (1 << k)) continue;
        ++numB;
        const float d2 = options.pattern.x[k] * options.pattern.x[k] + options.pattern.y[k] * options.pattern.y[k];
        if (d2 > farD2) farD2 = d2, farthest = k;
      }
      const double len = std::sqrt(double(farD2));
      const double scale = len > 0.0 ? (double(numB) / kSamples) / len : 0.0;
      table.offset[mask][0] = float(options.pattern.x[farthest] * scale);
      table.offset[mask][1] = float(options.pattern.y[farthest] * scale);
      table.source[mask] = OffsetSource::Fallback;
      continue;
    }
    table.source[mask] = f == one.get() ? OffsetSource::OneLine : OffsetSource::TwoLines;
    table.count[mask] = f->count[mask];
    table.meanCoverageB[mask] = f->coverageB[mask] / double(f->count[mask]);
    Fit best;
    best.error = HUGE_VAL;
    int bestQ = 0;
    for (int q = 0; q < 4; ++q) {
      const Fit fit = minimise(f->quadrant[mask][q]);
      if (fit.error < best.error) best = fit, bestQ = q;
    }
    const double sx = (bestQ & 1) ? -1.0 : 1.0, sy = (bestQ & 2) ? -1.0 : 1.0;
    table.offset[mask][0] = float(sx * best.a) + 0.0f;  // + 0.0f: no negative zero
    table.offset[mask][1] = float(sy * best.b) + 0.0f;
    table.rmsError[mask] = std::sqrt(std::max(0.0, best.error) / double(f->count[mask]));
  }
  return table;
}

namespace {
// A float literal that reads back as exactly v.
std::string floatLiteral(float v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", double(v));
  std::string s = buf;
  if (s.find_first_of(".e") == std::string::npos) s += ".0";
  return s + "f";
}
}  // namespace

std::string offsetTableSource(const GeneratedTable& table) {
  const GeneratorOptions& o = table.options;
  std::ostringstream out;
  out << "// SPDX-License-Identifier: Apache-2.0\n"
         "// GENERATED by crisp_rsaa_table (tools/rsaa_table, native/rsaa/table_generator.cpp): do not edit.\n"
         "// Regenerate with: cmake --build BUILD --target crisp_rsaa_table_regenerate\n"
         "// RSAA resampling offsets per 8-bit mask (seed 003, section 2.3.2): pixels, x right, y down.\n"
         "// Bit k of the mask is 1 iff sub-sample k lies on the centre's polygon.\n";
  out << "// pattern (x, y down):";
  for (int k = 0; k < kSamples; ++k) out << " (" << floatLiteral(o.pattern.x[k]) << ", " << floatLiteral(o.pattern.y[k]) << ")";
  out << "\n// seed " << o.seed << ", " << o.configurations << " one-line and " << o.configurations
      << " two-line configurations\n";
  out << "#include \"rsaa/offset_table.h\"\n\nnamespace crisp::rsaa {\n\n";
  out << "const Pattern kTablePattern = {\n    {";
  for (int k = 0; k < kSamples; ++k) out << (k ? ", " : "") << floatLiteral(o.pattern.x[k]);
  out << "},\n    {";
  for (int k = 0; k < kSamples; ++k) out << (k ? ", " : "") << floatLiteral(o.pattern.y[k]);
  out << "},\n};\nconst std::uint32_t kTableSeed = " << o.seed << "u;\nconst long kTableConfigurations = "
      << o.configurations << ";\n\n";
  out << "// {ox, oy},  // mask, source, configurations, rms coverage error, mean B coverage\n";
  out << "const float kOffsetTable[kMasks][2] = {\n";
  for (int m = 0; m < kMasks; ++m) {
    char comment[160];
    std::snprintf(comment, sizeof comment, "  // 0x%02x %s n=%ld rms=%.4f covB=%.4f", m, offsetSourceName(table.source[m]),
                  table.count[m], table.rmsError[m], table.meanCoverageB[m]);
    out << "    {" << floatLiteral(table.offset[m][0]) << ", " << floatLiteral(table.offset[m][1]) << "}," << comment
        << "\n";
  }
  out << "};\n\n}  // namespace crisp::rsaa\n";
  return out.str();
}

}  // namespace crisp::rsaa
