// SPDX-License-Identifier: Apache-2.0
// What the C API fuzz targets share: their view of libFuzzer's bytes (values
// read in order, zeros once the bytes run out, so every input is a whole
// sequence of calls), the check of an execute's output, the end of every
// sequence, the comparison of a sequence run with the output in place
// against the same sequence run with the output apart, and the seeds each
// target writes for its corpus (writeSeedsIfAsked).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <utility>
#include <vector>

#include "crisp/crisp.h"

namespace crisp_fuzz {

struct Reader {
  const std::uint8_t* p;
  std::size_t n;
  std::uint8_t byte() {
    if (!n) return 0;
    --n;
    return *p++;
  }
  // Any float, NaN and infinities included: four bytes as its bits.
  float number() {
    std::uint32_t bits = 0;
    for (int i = 0; i < 4; ++i) bits = bits << 8 | byte();
    float f;
    std::memcpy(&f, &bits, 4);
    return f;
  }
  std::string pick(const std::vector<std::string>& names) { return names[byte() % names.size()]; }
};

// The "output" view a filter writes: the last one crispSetFilterImage accepted (a refused
// one leaves the one before; checking a refused buffer gave b7cf39b's false positives).
struct OutputView {
  const unsigned char* ptr = nullptr;
  int channels = 0;
  std::size_t width = 0, height = 0, pixelBytes = 0, rowBytes = 0;
  explicit operator bool() const { return ptr != nullptr; }
  float at(std::size_t x, std::size_t y, int c) const {
    float v;
    std::memcpy(&v, ptr + y * rowBytes + x * pixelBytes + std::size_t(c) * 4, 4);
    return v;
  }
};

// crispSetFilterImage, and whether the filter took the image (this call's error only). When
// it took an "output", *output becomes its view; strides 0 = packed, as crisp.h says.
inline bool setImage(CrispFilter filter, const char* name, void* ptr, CrispFormat format, std::size_t width,
                     std::size_t height, std::size_t pixelBytes, std::size_t rowBytes, OutputView* output) {
  crispGetError(nullptr);
  crispSetFilterImage(filter, name, ptr, format, width, height, pixelBytes, rowBytes);
  if (crispGetError(nullptr) != CRISP_ERROR_NONE) return false;
  if (output && std::strcmp(name, "output") == 0) {
    // Only float formats are output formats; any other is refused above.
    const int channels = format >= CRISP_FORMAT_FLOAT && format <= CRISP_FORMAT_FLOAT4 ? int(format) : 0;
    const std::size_t pixel = pixelBytes ? pixelBytes : std::size_t(channels) * 4;
    *output = {static_cast<const unsigned char*>(ptr), channels, width, height, pixel, rowBytes ? rowBytes : pixel * width};
  }
  return true;
}

// crisp.h: every filter's output is finite. A trap on a NaN or an infinity in `output`.
inline void trapUnlessFinite(const OutputView& output) {
  for (std::size_t y = 0; y < output.height; ++y)
    for (std::size_t x = 0; x < output.width; ++x)
      for (int c = 0; c < output.channels; ++c)
        if (!std::isfinite(output.at(x, y, c))) __builtin_trap();  // an execute without error wrote it
}

// crispExecuteFilter, and whether it reported no error (this call's only); if so, the output
// it wrote is checked (trapUnlessFinite).
inline bool execute(CrispFilter filter, const OutputView& output) {
  crispGetError(nullptr);
  crispExecuteFilter(filter);
  if (crispGetError(nullptr) != CRISP_ERROR_NONE) return false;
  if (output) trapUnlessFinite(output);
  return true;
}

// The end of every sequence: one more commit and execute (whatever state the
// calls left; its output checked as every execute's, and `executed` told
// whether it reported no error, so that a target records it as its others),
// every error read, the handles released.
template <class Executed>
void finish(CrispContext context, CrispFilter filter, const OutputView& output, Executed&& executed) {
  crispCommitFilter(filter);
  executed(execute(filter, output));
  crispGetError(nullptr);
  crispReleaseFilter(filter);
  crispReleaseContext(context);
}

// ---- the output in place against the output apart ------------------------------------------------
// crisp.h: the "output" image may share an input's buffer (in place), and the result is the same as
// with separate buffers. A target runs the bytes' sequence once; if an execute without error wrote into
// the buffer of an input still set (the output's view the input's own: pointer, format, strides, the
// case crisp.h describes), it runs the sequence again from a fresh context and filter with the output
// in a buffer of its own of the same layout, and the two runs must write the same.

// What one run of a sequence wrote.
struct Trace {
  std::string filter;    // the type the run asked crispNewFilter for
  bool inPlace = false;  // an execute without error wrote into the buffer of an input still set
  std::vector<std::pair<bool, std::vector<float>>> executes;  // each one's "no error", and what it wrote
  std::vector<std::vector<float>> buffers;  // every buffer the bytes made, at the end (after finish)
};

// After an execute (`ok`: it reported no error): what it wrote into `output`, kept in `trace`. In the
// run apart, `copyTo` is the input's buffer the output would have been in (laid out as the output's
// view) and gets the values too, so that it holds what the run in place left there and both runs go
// on reading the same images; otherwise nullptr.
inline void recordExecute(Trace& trace, bool ok, const OutputView& output, void* copyTo) {
  trace.executes.emplace_back(ok, std::vector<float>());
  if (!ok || !output) return;
  std::vector<float>& values = trace.executes.back().second;
  for (std::size_t y = 0; y < output.height; ++y)
    for (std::size_t x = 0; x < output.width; ++x)
      for (int c = 0; c < output.channels; ++c) {
        values.push_back(output.at(x, y, c));
        if (copyTo)
          std::memcpy(static_cast<unsigned char*>(copyTo) + y * output.rowBytes + x * output.pixelBytes +
                          std::size_t(c) * 4,
                      &values.back(), 4);
      }
}

// Equal bit for bit, or both NaN (the payload may differ).
inline bool same(float a, float b) {
  std::uint32_t x, y;
  std::memcpy(&x, &a, 4);
  std::memcpy(&y, &b, 4);
  return x == y || (std::isnan(a) && std::isnan(b));
}

// A trap after a message saying where the two runs differ.
[[noreturn]] inline void differ(const char* target, const char* what, std::size_t at, std::size_t value,
                                float inPlace, float apart) {
  std::fprintf(stderr, "%s: the output in place differs from the output apart: %s %zu, value %zu: %a vs %a\n",
               target, what, at, value, double(inPlace), double(apart));
  __builtin_trap();
}

// Every execute's error or output and, at the end, every buffer (padding included: what was written
// where it should not be) equal bit for bit, NaNs equal to NaNs; a trap naming the first difference.
inline void compare(const char* target, const Trace& inPlace, const Trace& apart) {
  if (inPlace.executes.size() != apart.executes.size() || inPlace.buffers.size() != apart.buffers.size())
    differ(target, "the number of executes or buffers", 0, 0, 0, 0);  // the same bytes: a harness bug
  for (std::size_t i = 0; i < inPlace.executes.size(); ++i) {
    const auto& [ok, values] = inPlace.executes[i];
    const auto& [okApart, valuesApart] = apart.executes[i];
    if (ok != okApart || values.size() != valuesApart.size())
      differ(target, "execute (an error or the output's size in one run only)", i, 0, ok, okApart);
    for (std::size_t k = 0; k < values.size(); ++k)
      if (!same(values[k], valuesApart[k])) differ(target, "execute", i, k, values[k], valuesApart[k]);
  }
  for (std::size_t i = 0; i < inPlace.buffers.size(); ++i)
    for (std::size_t k = 0; k < std::min(inPlace.buffers[i].size(), apart.buffers[i].size()); ++k)
      if (!same(inPlace.buffers[i][k], apart.buffers[i][k]))
        differ(target, "buffer", i, k, inPlace.buffers[i][k], apart.buffers[i][k]);
}

// run(apart, trace) runs the bytes' sequence from a fresh context and filter, with the output where the
// bytes put it (apart = false) or, apart, in a buffer of its own. The second run only when the first
// ran in place (a temporal filter's history makes the whole sequence matter, so it is the whole run).
template <class Run>
void checkInPlace(const char* target, Run&& run) {
  Trace inPlace;
  run(false, inPlace);
  if (!inPlace.inPlace) return;
  Trace apart;
  run(true, apart);
  compare(target, inPlace, apart);
}

// ---- seeds: inputs that reach the in-place check from the start ---------------------------------------
// scripts/test.sh fuzzes each target for 30 s. From an empty corpus, fuzz_c_api took 58-75 s to trap a
// filter made unsafe in place (fxaa without its staged copy of the input, repair's in-place path reading
// what it had already written): the bytes must first make a valid colour image, put the output on its
// buffer and execute. So each target writes seeds that do, beside the run() that reads them, in its own
// code (no opaque binaries), and the fuzz stage starts from them:
//   CRISP_FUZZ_WRITE_SEEDS=DIR build-fuzz/bin/fuzz_c_api
// runs each seed once (the run in place), checks that it still reaches what it is for (the filter, the
// output in an input's buffer or apart, at least so many executes without error that wrote an output),
// writes it to DIR/<name> and exits 0. A seed that no longer reaches its state (the bytes a run() reads
// changed under it) is not written: a message names it, and the exit status is 1.

// The bytes a Reader reads back as the values written.
struct Writer {
  std::vector<std::uint8_t> bytes;
  void byte(int b) { bytes.push_back(std::uint8_t(b)); }
  void number(float f) {  // Reader::number: the bits, high byte first
    std::uint32_t bits;
    std::memcpy(&bits, &f, 4);
    for (int i = 3; i >= 0; --i) byte(int(bits >> (8 * i) & 0xFF));
  }
  void pick(const std::vector<std::string>& names, const std::string& name) {  // Reader::pick
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == name) return byte(int(i));
    std::fprintf(stderr, "crisp_fuzz::Writer: '%s' is not one of the names a seed picks from\n", name.c_str());
    std::abort();
  }
};

struct Seed {
  std::string name;  // its file name
  std::vector<std::uint8_t> bytes;
  // What its run in place must reach: the filter, the output in an input's buffer (Trace::inPlace) or
  // not, and at least `executes` executes without error that wrote an output.
  std::string filter;
  bool inPlace = true;
  int executes = 2;
};

// Executes without error that wrote an output.
inline int writingExecutes(const Trace& trace) {
  int n = 0;
  for (const auto& [ok, values] : trace.executes) n += ok && !values.empty();
  return n;
}

// With CRISP_FUZZ_WRITE_SEEDS=DIR set: run(data, size, apart, trace) once on each seed (in place), each
// that reaches its state written to DIR/<name>; then the process exits, 0 if every seed did. Without it,
// nothing. From LLVMFuzzerInitialize (libFuzzer calls it before it reads any flag or input).
template <class Run>
void writeSeedsIfAsked(const char* target, const std::vector<Seed>& seeds, Run&& run) {
  const char* dir = std::getenv("CRISP_FUZZ_WRITE_SEEDS");
  if (!dir) return;
  bool all = true;
  for (const Seed& seed : seeds) {
    Trace trace;
    run(seed.bytes.data(), seed.bytes.size(), false, trace);
    const int executes = writingExecutes(trace);
    if (trace.filter != seed.filter || trace.inPlace != seed.inPlace || executes < seed.executes) {
      std::fprintf(stderr,
                   "%s: seed '%s' no longer reaches its state (did the bytes the target reads change?): filter "
                   "'%s', output %s, %d executes that wrote it; it is for '%s', %s, at least %d\n",
                   target, seed.name.c_str(), trace.filter.c_str(), trace.inPlace ? "in place" : "apart", executes,
                   seed.filter.c_str(), seed.inPlace ? "in place" : "apart", seed.executes);
      all = false;
      continue;
    }
    const std::string path = std::string(dir) + "/" + seed.name;
    std::ofstream out(path, std::ios::binary);
    out.write(reinterpret_cast<const char*>(seed.bytes.data()), std::streamsize(seed.bytes.size()));
    if (!out.flush()) {
      std::fprintf(stderr, "%s: cannot write the seed %s\n", target, path.c_str());
      all = false;
      continue;
    }
    std::fprintf(stderr, "%s: seed %s: %zu bytes, %s, output %s, %d executes that wrote it\n", target,
                 seed.name.c_str(), seed.bytes.size(), trace.filter.c_str(), trace.inPlace ? "in place" : "apart",
                 executes);
  }
  std::exit(all ? 0 : 1);
}

}  // namespace crisp_fuzz
