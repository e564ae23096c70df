// SPDX-License-Identifier: Apache-2.0
// Header-only C++ wrapper over the C API (crisp.h): RAII handles, and every
// failed call turns into a crisp::Error exception carrying the C error code.
#pragma once

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include "crisp/crisp.h"

namespace crisp {

class Error : public std::runtime_error {
 public:
  Error(CrispError code, const std::string& message) : std::runtime_error(message), code_(code) {}
  CrispError code() const { return code_; }

 private:
  CrispError code_;
};

// Throws if the calling thread has an unqueried error.
inline void checkError() {
  const char* message = nullptr;
  CrispError code = crispGetError(&message);
  if (code != CRISP_ERROR_NONE) throw Error(code, message ? message : "unknown error");
}

template <class Handle, void (*Retain)(Handle), void (*Release)(Handle)>
class Ref {
 public:
  Ref() = default;
  explicit Ref(Handle h) : h_(h) {}
  Ref(const Ref& o) : h_(o.h_) {
    if (h_) Retain(h_);
  }
  Ref(Ref&& o) noexcept : h_(std::exchange(o.h_, nullptr)) {}
  Ref& operator=(Ref o) noexcept {
    std::swap(h_, o.h_);
    return *this;
  }
  ~Ref() {
    if (h_) Release(h_);
  }
  Handle handle() const { return h_; }
  explicit operator bool() const { return h_ != nullptr; }

 protected:
  Handle h_ = nullptr;
};

class FilterRef : public Ref<CrispFilter, crispRetainFilter, crispReleaseFilter> {
 public:
  using Ref::Ref;
  void setImage(const char* name, void* ptr, CrispFormat format, size_t width, size_t height,
                size_t pixelByteStride = 0, size_t rowByteStride = 0) {
    crispSetFilterImage(h_, name, ptr, format, width, height, pixelByteStride, rowByteStride);
    checkError();
  }
  void unsetImage(const char* name) {
    crispUnsetFilterImage(h_, name);
    checkError();
  }
  void set(const char* name, int v) {
    crispSetFilterInt(h_, name, v);
    checkError();
  }
  void set(const char* name, float v) {
    crispSetFilterFloat(h_, name, v);
    checkError();
  }
  // A double (a literal such as 0.25) sets a float parameter; without this overload the call was
  // ambiguous between the int, float and bool ones and did not compile. One beyond float's range
  // reaches the library as an infinity: its error says so, and names the value given.
  void set(const char* name, double v) {
    const float f = static_cast<float>(v);
    try {
      set(name, f);
    } catch (const Error& e) {
      if (!std::isinf(f) || std::isinf(v)) throw;
      std::ostringstream message;
      message << e.what() << " (given " << v << ", beyond a float's range)";
      throw Error(e.code(), message.str());
    }
  }
  void set(const char* name, bool v) {
    crispSetFilterBool(h_, name, v ? 1 : 0);
    checkError();
  }
  void set(const char* name, const char* v) {
    crispSetFilterString(h_, name, v);
    checkError();
  }
  template <class T>
  T get(const char* name) const;
  std::string doc() const {
    const char* d = crispGetFilterDoc(h_);
    checkError();
    return d;
  }
  void commit() {
    crispCommitFilter(h_);
    checkError();
  }
  void execute() {
    crispExecuteFilter(h_);
    checkError();
  }
  void reset() {
    crispResetFilter(h_);
    checkError();
  }
};

template <>
inline int FilterRef::get<int>(const char* name) const {
  int v = crispGetFilterInt(h_, name);
  checkError();
  return v;
}
template <>
inline float FilterRef::get<float>(const char* name) const {
  float v = crispGetFilterFloat(h_, name);
  checkError();
  return v;
}
template <>
inline bool FilterRef::get<bool>(const char* name) const {
  int v = crispGetFilterBool(h_, name);
  checkError();
  return v != 0;
}
template <>
inline std::string FilterRef::get<std::string>(const char* name) const {
  const char* v = crispGetFilterString(h_, name);
  checkError();
  return v;
}

class ContextRef : public Ref<CrispContext, crispRetainContext, crispReleaseContext> {
 public:
  using Ref::Ref;
  static ContextRef create() {
    CrispContext c = crispNewContext();
    checkError();
    return ContextRef(c);
  }
  void set(const char* name, int v) {
    crispSetContextInt(h_, name, v);
    checkError();
  }
  int get(const char* name) const {
    int v = crispGetContextInt(h_, name);
    checkError();
    return v;
  }
  void commit() {
    crispCommitContext(h_);
    checkError();
  }
  FilterRef newFilter(const char* type) {
    CrispFilter f = crispNewFilter(h_, type);
    checkError();
    return FilterRef(f);
  }
  CrispMetrics compare(const float* reference, const float* test, CrispFormat format, size_t width, size_t height,
                       const float* mask = nullptr) {
    CrispMetrics m{};
    crispCompareImages(h_, reference, test, format, width, height, mask, &m);
    checkError();
    return m;
  }
  void writeImage(const char* path, const float* ptr, CrispFormat format, size_t width, size_t height,
                  size_t pixelByteStride = 0, size_t rowByteStride = 0) {
    crispWriteImage(h_, path, ptr, format, width, height, pixelByteStride, rowByteStride);
    checkError();
  }
  // An .exr at bitDepth 16 or 32 in one of Blender's codecs (crispWriteImageEXR).
  void writeImageEXR(const char* path, const float* ptr, CrispFormat format, size_t width, size_t height,
                     int bitDepth, const char* compression, size_t pixelByteStride = 0, size_t rowByteStride = 0) {
    crispWriteImageEXR(h_, path, ptr, format, width, height, pixelByteStride, rowByteStride, bitDepth, compression);
    checkError();
  }
};

}  // namespace crisp
