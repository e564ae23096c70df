// SPDX-License-Identifier: Apache-2.0
// The C boundary: every extern "C" function of crisp.h lives here. Nothing
// thrown inside the library crosses it; errors go to the per-thread state.
#include <cstring>
#include <exception>
#include <map>
#include <new>
#include <string>

#include "core/context.h"
#include "core/error.h"
#include "core/filter.h"
#include "io/frame.h"
#include "io/subsamples.h"
#include "metrics/metrics.h"
#include "motion/reconstruct.h"
#include "crisp/crisp.h"

struct CrispContextImpl {
  crisp::Context ctx;
};
struct CrispFilterImpl {
  std::unique_ptr<crisp::Filter> filter;
  CrispContextImpl* owner = nullptr;
  std::atomic<int> refCount{1};
  // The strings the getters return, one per parameter name and one each for the doc and the
  // info: a string stays valid until its own value changes (crisp.h), whatever else is read.
  std::map<std::string, std::string> strings;
  std::string doc, info;
  const char* keep(std::string& slot, std::string value) {
    if (slot != value) slot = std::move(value);
    return slot.c_str();
  }
};
struct CrispFrameImpl {
  crisp::Frame frame;
  std::string passes;
};

namespace {

struct ThreadError {
  CrispError code = CRISP_ERROR_NONE;
  std::string message;
  std::string returned;  // what the last crispGetError handed out
};
thread_local ThreadError tError;

void setError(CrispError code, const std::string& message) {
  if (tError.code == CRISP_ERROR_NONE) {  // keep the first unqueried error
    tError.code = code;
    tError.message = message;
  }
}

template <class F, class R = decltype(std::declval<F>()())>
R guarded(F&& f, R fallback = R()) {
  try {
    return f();
  } catch (const crisp::Exception& e) {
    setError(e.code(), e.what());
  } catch (const std::bad_alloc&) {
    setError(CRISP_ERROR_OUT_OF_MEMORY, "out of memory");
  } catch (const std::exception& e) {
    setError(CRISP_ERROR_UNKNOWN, e.what());
  } catch (...) {
    setError(CRISP_ERROR_UNKNOWN, "unknown error");
  }
  return fallback;
}

template <class F>
void guardedVoid(F&& f) {
  guarded([&] {
    f();
    return 0;
  });
}

void need(const void* handle, const char* what) {
  if (!handle) crisp::invalidArgument(std::string(what) + " handle is NULL");
}
std::string nameOf(const char* name, const char* what) {
  if (!name) crisp::invalidArgument(std::string(what) + " name is NULL");
  return name;
}

void releaseContextImpl(CrispContextImpl* c) {
  if (c && --c->ctx.refCount == 0) delete c;
}

}  // namespace

extern "C" {

int crispGetVersion(void) { return CRISP_VERSION; }

const char* crispGetVersionString(void) {
  static const std::string v = std::to_string(CRISP_VERSION_MAJOR) + "." + std::to_string(CRISP_VERSION_MINOR) + "." +
                               std::to_string(CRISP_VERSION_PATCH);
  return v.c_str();
}

CrispError crispGetError(const char** outMessage) {
  CrispError code = tError.code;
  tError.returned = tError.message;
  tError.code = CRISP_ERROR_NONE;
  tError.message.clear();
  if (outMessage) *outMessage = code == CRISP_ERROR_NONE ? nullptr : tError.returned.c_str();
  return code;
}

CrispContext crispNewContext(void) {
  return guarded([]() -> CrispContext { return new CrispContextImpl(); }, CrispContext(nullptr));
}

void crispRetainContext(CrispContext context) {
  guardedVoid([&] {
    need(context, "context");
    context->ctx.refCount++;
  });
}

void crispReleaseContext(CrispContext context) {
  guardedVoid([&] { releaseContextImpl(context); });
}

void crispSetContextInt(CrispContext context, const char* name, int value) {
  guardedVoid([&] {
    need(context, "context");
    context->ctx.setInt(nameOf(name, "parameter"), value);
  });
}

int crispGetContextInt(CrispContext context, const char* name) {
  return guarded([&] {
    need(context, "context");
    return context->ctx.getInt(nameOf(name, "parameter"));
  });
}

void crispCommitContext(CrispContext context) {
  guardedVoid([&] {
    need(context, "context");
    context->ctx.commit();
  });
}

const char* crispGetFilterTypes(void) { return crisp::filterTypesJoined(); }

CrispFilter crispNewFilter(CrispContext context, const char* type) {
  return guarded(
      [&]() -> CrispFilter {
        need(context, "context");
        auto impl = new CrispFilterImpl();
        try {
          impl->filter = crisp::createFilter(context->ctx, nameOf(type, "filter type"));
        } catch (...) {
          delete impl;
          throw;
        }
        impl->owner = context;
        context->ctx.refCount++;  // the context lives as long as its filters
        return impl;
      },
      CrispFilter(nullptr));
}

void crispRetainFilter(CrispFilter filter) {
  guardedVoid([&] {
    need(filter, "filter");
    filter->refCount++;
  });
}

void crispReleaseFilter(CrispFilter filter) {
  guardedVoid([&] {
    if (filter && --filter->refCount == 0) {
      CrispContextImpl* owner = filter->owner;
      delete filter;
      releaseContextImpl(owner);
    }
  });
}

void crispSetFilterImage(CrispFilter filter, const char* name, void* ptr, CrispFormat format, size_t width,
                         size_t height, size_t pixelByteStride, size_t rowByteStride) {
  guardedVoid([&] {
    need(filter, "filter");
    std::string n = nameOf(name, "image");
    if (!ptr) {  // crisp.h: NULL unsets the image, whatever the other arguments say
      filter->filter->unsetImage(n);
      return;
    }
    const int formatValue = static_cast<int>(format);  // any int from C: compared as one, never as the enum
    if (formatValue < CRISP_FORMAT_FLOAT || formatValue > CRISP_FORMAT_RSAA_SUBSAMPLES)
      crisp::invalidArgument("image '" + n + "': unknown format " + std::to_string(formatValue));
    if (width > (1u << 16) || height > (1u << 16))
      crisp::invalidArgument("image '" + n + "': size " + std::to_string(width) + "x" + std::to_string(height) +
                             " is out of range [1, 65536]");
    filter->filter->setImage(n, crisp::makeView(ptr, crisp::Format(format), int(width), int(height), pixelByteStride,
                                                rowByteStride));
  });
}

void crispUnsetFilterImage(CrispFilter filter, const char* name) {
  guardedVoid([&] {
    need(filter, "filter");
    filter->filter->unsetImage(nameOf(name, "image"));
  });
}

#define CRISP_SETTER(Suffix, CType, Method, Cast)                            \
  void crispSetFilter##Suffix(CrispFilter filter, const char* name, CType v) { \
    guardedVoid([&] {                                                          \
      need(filter, "filter");                                                  \
      const std::string key = nameOf(name, "parameter");                       \
      filter->filter->params().Method(key, Cast(v));                           \
      filter->filter->markDirty("parameter '" + key + "' was set");            \
    });                                                                        \
  }
CRISP_SETTER(Int, int, setInt, int)
CRISP_SETTER(Float, float, setFloat, float)
CRISP_SETTER(Bool, int, setBool, bool)
#undef CRISP_SETTER

void crispSetFilterString(CrispFilter filter, const char* name, const char* value) {
  guardedVoid([&] {
    need(filter, "filter");
    const std::string key = nameOf(name, "parameter");
    if (!value)
      crisp::invalidArgument(std::string("filter '") + filter->filter->type() + "': parameter '" + key + "': value is NULL");
    filter->filter->params().setString(key, value);
    filter->filter->markDirty("parameter '" + key + "' was set");
  });
}

int crispGetFilterInt(CrispFilter filter, const char* name) {
  return guarded([&] {
    need(filter, "filter");
    return filter->filter->params().getInt(nameOf(name, "parameter"));
  });
}

float crispGetFilterFloat(CrispFilter filter, const char* name) {
  return guarded([&] {
    need(filter, "filter");
    return filter->filter->params().getFloat(nameOf(name, "parameter"));
  });
}

int crispGetFilterBool(CrispFilter filter, const char* name) {
  return guarded([&] {
    need(filter, "filter");
    return int(filter->filter->params().getBool(nameOf(name, "parameter")));
  });
}

const char* crispGetFilterString(CrispFilter filter, const char* name) {
  return guarded(
      [&]() -> const char* {
        need(filter, "filter");
        const std::string n = nameOf(name, "parameter");
        std::string value = filter->filter->params().getString(n);
        return filter->keep(filter->strings[n], std::move(value));
      },
      static_cast<const char*>(nullptr));
}

const char* crispGetFilterDoc(CrispFilter filter) {
  return guarded(
      [&]() -> const char* {
        need(filter, "filter");
        return filter->keep(filter->doc, filter->filter->doc());
      },
      static_cast<const char*>(nullptr));
}

const char* crispGetFilterInfo(CrispFilter filter) {
  return guarded(
      [&]() -> const char* {
        need(filter, "filter");
        return filter->keep(filter->info, filter->filter->infoJson());
      },
      static_cast<const char*>(nullptr));
}

void crispCommitFilter(CrispFilter filter) {
  guardedVoid([&] {
    need(filter, "filter");
    filter->filter->commit();
  });
}

void crispExecuteFilter(CrispFilter filter) {
  guardedVoid([&] {
    need(filter, "filter");
    filter->filter->execute();
  });
}

void crispResetFilter(CrispFilter filter) {
  guardedVoid([&] {
    need(filter, "filter");
    filter->filter->reset();
  });
}

CrispFrame crispLoadFrame(CrispContext context, const char* path) {
  return guarded(
      [&]() -> CrispFrame {
        need(context, "context");
        auto impl = std::make_unique<CrispFrameImpl>();
        impl->frame = crisp::readFrame(nameOf(path, "file"));
        impl->passes = impl->frame.passList();
        return impl.release();
      },
      CrispFrame(nullptr));
}

void crispReleaseFrame(CrispFrame frame) { delete frame; }

int crispGetFrameWidth(CrispFrame frame) {
  return guarded([&] {
    need(frame, "frame");
    return frame->frame.width;
  });
}

int crispGetFrameHeight(CrispFrame frame) {
  return guarded([&] {
    need(frame, "frame");
    return frame->frame.height;
  });
}

long long crispGetFrameNonFiniteColour(CrispFrame frame) {
  return guarded([&] {
    need(frame, "frame");
    return static_cast<long long>(frame->frame.nonFiniteColour);
  });
}

const char* crispGetFramePasses(CrispFrame frame) {
  return guarded(
      [&]() -> const char* {
        need(frame, "frame");
        return frame->passes.c_str();
      },
      static_cast<const char*>(nullptr));
}

void* crispGetFramePass(CrispFrame frame, const char* role, CrispFormat* outFormat) {
  return guarded(
      [&]() -> void* {
        need(frame, "frame");
        const crisp::Image& im = frame->frame.pass(nameOf(role, "pass"));
        if (outFormat) *outFormat = CrispFormat(int(im.format));
        return const_cast<float*>(im.data.data());
      },
      static_cast<void*>(nullptr));
}

void crispReconstructFrameMotion(CrispContext context, CrispFrame frame, const char* previousSidecar,
                                 const char* nextSidecar) {
  guardedVoid([&] {
    need(context, "context");
    need(frame, "frame");
    crisp::reconstructFrameMotion(frame->frame, nameOf(previousSidecar, "previous sidecar"),
                                  nextSidecar ? std::string(nextSidecar) : std::string(), context->ctx.numThreads());
    frame->passes = frame->frame.passList();
  });
}

void crispAttachFrameSubsamples(CrispContext context, CrispFrame frame, CrispFilter filter) {
  guardedVoid([&] {
    need(context, "context");
    need(frame, "frame");
    try {
      if (filter) {
        crisp::attachRsaaInputs(*filter->filter, frame->frame);
      } else if (!frame->frame.has(crisp::subsamplePass(0))) {
        crisp::attachSubsamples(frame->frame, crisp::sidecarPathFor(frame->frame.path));
      }
    } catch (...) {  // the filter refused the camera after the passes were added: list them still
      frame->passes = frame->frame.passList();
      throw;
    }
    frame->passes = frame->frame.passList();
  });
}

namespace {

void writeViewChecked(CrispContext context, const char* path, const void* ptr, CrispFormat format, size_t width,
                      size_t height, size_t pixelByteStride, size_t rowByteStride, const crisp::ExrStorage& storage) {
  need(context, "context");
  std::string p = nameOf(path, "file");
  if (!ptr) crisp::invalidArgument("image to write to '" + p + "' is NULL");
  if (format != CRISP_FORMAT_FLOAT3 && format != CRISP_FORMAT_FLOAT4)
    crisp::invalidArgument("image to write to '" + p + "' must be float3 or float4");
  if (width == 0 || height == 0 || width > (1u << 16) || height > (1u << 16))
    crisp::invalidArgument("image to write to '" + p + "' has size " + std::to_string(width) + "x" +
                           std::to_string(height));
  const crisp::ImageView view = crisp::makeView(const_cast<void*>(ptr), crisp::Format(format), int(width),
                                                int(height), pixelByteStride, rowByteStride);
  crisp::checkViewLayout("image to write to '" + p + "'", view);  // as crispSetFilterImage checks its views
  crisp::writeImage(p, view, storage);
}

}  // namespace

void crispWriteImage(CrispContext context, const char* path, const void* ptr, CrispFormat format, size_t width,
                     size_t height, size_t pixelByteStride, size_t rowByteStride) {
  guardedVoid([&] {
    writeViewChecked(context, path, ptr, format, width, height, pixelByteStride, rowByteStride, {});
  });
}

void crispWriteImageEXR(CrispContext context, const char* path, const void* ptr, CrispFormat format, size_t width,
                        size_t height, size_t pixelByteStride, size_t rowByteStride, int bitDepth,
                        const char* compression) {
  guardedVoid([&] {
    const std::string p = nameOf(path, "file");
    if (crisp::lowerExtension(p) != ".exr")
      crisp::invalidArgument("crispWriteImageEXR writes .exr files, not '" + p + "'");
    if (bitDepth != 16 && bitDepth != 32)
      crisp::invalidArgument("EXR bit depth " + std::to_string(bitDepth) + " for '" + p + "' (16 or 32)");
    crisp::ExrStorage storage;
    storage.half = bitDepth == 16;
    if (compression) storage.compression = compression;
    crisp::checkExrStorage(storage);
    writeViewChecked(context, path, ptr, format, width, height, pixelByteStride, rowByteStride, storage);
  });
}

void crispCompareImages(CrispContext context, const void* reference, const void* test, CrispFormat format,
                        size_t width, size_t height, const float* mask, CrispMetrics* outMetrics) {
  guardedVoid([&] {
    need(context, "context");
    if (!reference || !test || !outMetrics) crisp::invalidArgument("crispCompareImages: reference, test and outMetrics must not be NULL");
    if (format != CRISP_FORMAT_FLOAT3 && format != CRISP_FORMAT_FLOAT4)
      crisp::invalidArgument("crispCompareImages: images must be float3 or float4");
    if (width == 0 || height == 0 || width > (1u << 16) || height > (1u << 16))
      crisp::invalidArgument("crispCompareImages: size " + std::to_string(width) + "x" + std::to_string(height) + " is out of range");
    const int c = int(format);
    auto copy = [&](const void* p) {
      crisp::Image im(int(width), int(height), c);
      std::memcpy(im.data.data(), p, im.data.size() * sizeof(float));
      return im;
    };
    crisp::Image ref = copy(reference), tst = copy(test);
    crisp::Image m;
    if (mask) {
      m = crisp::Image(int(width), int(height), 1);
      std::memcpy(m.data.data(), mask, m.data.size() * sizeof(float));
    }
    crisp::Metrics r = crisp::compareImages(ref, tst, mask ? &m : nullptr, {}, context->ctx.numThreads());
    *outMetrics = CrispMetrics{r.mse, r.rmse, r.psnr, r.snr, r.ssim, r.flip};
  });
}

}  // extern "C"
