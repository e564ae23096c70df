// SPDX-License-Identifier: Apache-2.0
// The RSAA offset table (seed 003, 2.3.2): the shipped table and its source
// file equal a fresh run of the generator with the same pattern, seed and
// count; the pattern is the add-on's; the generator is deterministic, depends
// on its seed and pattern, and its entries make geometric sense.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include "core/error.h"
#include "rsaa/offset_table.h"
#include "rsaa/table_generator.h"

using namespace crisp;
using namespace crisp::rsaa;

namespace {

// The repository root, from this file's path (tests/unit/test_rsaa_table.cpp).
std::string repoFile(const std::string& relative) {
  std::string here = __FILE__;
  const std::size_t cut = here.rfind("tests/unit/");
  return here.substr(0, cut) + relative;
}

std::string readText(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

bool sameBits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

GeneratorOptions shippedOptions() {
  GeneratorOptions o;
  o.pattern = kTablePattern;
  o.seed = kTableSeed;
  o.configurations = kTableConfigurations;
  return o;
}

}  // namespace

// The full-count run takes about a second: the check runs the real thing.
TEST(RsaaTable, ShippedTableEqualsFreshRun) {
  const GeneratedTable fresh = generateOffsetTable(shippedOptions());
  int mismatches = 0;
  for (int m = 0; m < kMasks; ++m)
    for (int c = 0; c < 2; ++c)
      if (!sameBits(fresh.offset[m][c], kOffsetTable[m][c])) {
        if (++mismatches < 5)
          ADD_FAILURE() << "mask " << m << " component " << c << ": shipped " << kOffsetTable[m][c] << ", fresh "
                        << fresh.offset[m][c];
      }
  EXPECT_EQ(mismatches, 0) << "regenerate with: cmake --build BUILD --target crisp_rsaa_table_regenerate";
  // The source file too (provenance comments included).
  const std::string shipped = readText(repoFile("native/rsaa/offset_table.cpp"));
  ASSERT_FALSE(shipped.empty()) << "cannot read native/rsaa/offset_table.cpp";
  EXPECT_TRUE(shipped == offsetTableSource(fresh)) << "native/rsaa/offset_table.cpp differs from a fresh run";
}

TEST(RsaaTable, ShippedWithTheDefaultPatternSeedAndCount) {
  for (int k = 0; k < kSamples; ++k) {
    EXPECT_TRUE(sameBits(kTablePattern.x[k], kDefaultPattern.x[k])) << k;
    EXPECT_TRUE(sameBits(kTablePattern.y[k], kDefaultPattern.y[k])) << k;
  }
  EXPECT_EQ(kTableSeed, kDefaultTableSeed);
  EXPECT_EQ(kTableConfigurations, kDefaultTableConfigurations);
}

// The add-on renders sub-sample k at RSAA_PATTERN[k] (pixels, y UP); the
// library's pattern is the same points with y down.
TEST(RsaaTable, PatternIsTheAddonsWithYFlipped) {
  const std::string py = readText(repoFile("addon/crisp/render.py"));
  ASSERT_FALSE(py.empty()) << "cannot read addon/crisp/render.py";
  const std::size_t at = py.find("RSAA_PATTERN = [");
  ASSERT_NE(at, std::string::npos);
  const std::size_t end = py.find(']', at + 16);
  const std::string list = py.substr(at, end - at);
  std::regex pair(R"(\(\s*(-?[0-9.]+)\s*,\s*(-?[0-9.]+)\s*\))");
  int k = 0;
  for (auto it = std::sregex_iterator(list.begin(), list.end(), pair); it != std::sregex_iterator(); ++it, ++k) {
    ASSERT_LT(k, kSamples);
    EXPECT_EQ(std::stof((*it)[1]), kDefaultPattern.x[k]) << "sample " << k;
    EXPECT_EQ(-std::stof((*it)[2]), kDefaultPattern.y[k]) << "sample " << k;
  }
  EXPECT_EQ(k, kSamples);
}

TEST(RsaaTable, DeterministicAndSeedAndPatternDependent) {
  GeneratorOptions o;
  o.configurations = 20000;
  const GeneratedTable a = generateOffsetTable(o), b = generateOffsetTable(o);
  EXPECT_EQ(offsetTableSource(a), offsetTableSource(b));
  o.seed += 1;
  const GeneratedTable c = generateOffsetTable(o);
  int differ = 0;
  for (int m = 0; m < kMasks; ++m) differ += !sameBits(a.offset[m][0], c.offset[m][0]);
  EXPECT_GT(differ, 10);
  // A pattern mirrored in x gives the mirrored table (up to sampling noise).
  GeneratorOptions mirrored;
  mirrored.configurations = 200000;
  for (int k = 0; k < kSamples; ++k) mirrored.pattern.x[k] = -kDefaultPattern.x[k];
  const GeneratedTable mt = generateOffsetTable(mirrored);
  int compared = 0;
  for (int m = 0; m < kMasks; ++m) {
    if (mt.source[m] != OffsetSource::OneLine || mt.count[m] < 2000) continue;
    EXPECT_NEAR(mt.offset[m][0], -kOffsetTable[m][0], 0.08) << "mask " << m;
    EXPECT_NEAR(mt.offset[m][1], kOffsetTable[m][1], 0.08) << "mask " << m;
    ++compared;
  }
  EXPECT_GT(compared, 10);
}

TEST(RsaaTable, EntriesMakeGeometricSense) {
  const GeneratedTable t = generateOffsetTable(shippedOptions());
  EXPECT_EQ(t.source[255], OffsetSource::Centre);
  EXPECT_EQ(kOffsetTable[255][0], 0.0f);
  EXPECT_EQ(kOffsetTable[255][1], 0.0f);
  int oneLine = 0, twoLines = 0, fallback = 0;
  for (int m = 0; m < kMasks; ++m) {
    EXPECT_LE(std::fabs(kOffsetTable[m][0]), 1.0f);
    EXPECT_LE(std::fabs(kOffsetTable[m][1]), 1.0f);
    oneLine += t.source[m] == OffsetSource::OneLine;
    twoLines += t.source[m] == OffsetSource::TwoLines;
    fallback += t.source[m] == OffsetSource::Fallback;
    if (t.source[m] == OffsetSource::OneLine) {
      EXPECT_LT(t.rmsError[m], 0.1) << "mask " << m;
    }
  }
  std::printf("[ rsaa ] table: %d one-line, %d two-line, %d fallback masks\n", oneLine, twoLines, fallback);
  EXPECT_GT(oneLine, 16);
  EXPECT_GT(twoLines, 16);
  // One sample alone on the other polygon: the offset leans towards it.
  for (int k = 0; k < kSamples; ++k) {
    const int m = 255 & ~(1 << k);
    ASSERT_EQ(t.source[m], OffsetSource::OneLine) << k;
    const float dot = kOffsetTable[m][0] * kDefaultPattern.x[k] + kOffsetTable[m][1] * kDefaultPattern.y[k];
    EXPECT_GT(dot, 0.0f) << "sample " << k;
  }
  // Half of the samples cut off by a vertical line: mostly horizontal offset,
  // about half a pixel (mean coverage ~0.4).
  int right = 0;
  for (int k = 0; k < kSamples; ++k)
    if (kDefaultPattern.x[k] > 0.0f) right |= 1 << k;
  const int m = 255 & ~right;
  EXPECT_GT(kOffsetTable[m][0], 0.25f);
  EXPECT_LT(std::fabs(kOffsetTable[m][1]), 0.6f * kOffsetTable[m][0]);
}

TEST(RsaaTable, BadOptionsAreRejected) {
  GeneratorOptions o;
  o.configurations = 0;
  EXPECT_THROW(generateOffsetTable(o), Exception);
  o = GeneratorOptions();
  o.pattern.x[3] = 0.5f;
  EXPECT_THROW(generateOffsetTable(o), Exception);
  o = GeneratorOptions();
  o.pattern.y[0] = std::nanf("");
  EXPECT_THROW(generateOffsetTable(o), Exception);
}
