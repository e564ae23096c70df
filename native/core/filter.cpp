// SPDX-License-Identifier: Apache-2.0
#include "core/filter.h"

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <new>
#include <sstream>

#include "core/color.h"
#include "core/error.h"
#include "core/parallel.h"

namespace crisp {


Filter::Filter(Context& context, std::vector<ParamSpec> params, std::vector<ImageRole> roles)
    : context_(context), params_(std::move(params)), roles_(std::move(roles)) {
  context_.refCount++;
}

Filter::~Filter() { context_.refCount--; }

static const ImageRole* findRole(const std::vector<ImageRole>& roles, const std::string& name) {
  for (const ImageRole& r : roles)
    if (name == r.name) return &r;
  return nullptr;
}

static std::string roleList(const std::vector<ImageRole>& roles) {
  std::string s;
  for (const ImageRole& r : roles) s += std::string(s.empty() ? "" : ", ") + r.name;
  return s;
}

// What setImage accepts for a role, in the words of crisp.h's formats.
static std::string acceptedFormats(const ImageRole& r) {
  if (r.isUint) return "uint, or float read as its bits";
  if (r.minChannels == kRsaaSubsampleWords && r.maxChannels == kRsaaSubsampleWords)
    return std::string(formatName(Format::RsaaSubsamples)) + " (CRISP_FORMAT_RSAA_SUBSAMPLES)";
  return std::to_string(r.minChannels) + ".." + std::to_string(r.maxChannels) + " float channels";
}

void Filter::setImage(const std::string& name, const ImageView& view) {
  const ImageRole* role = findRole(roles_, name);
  if (!role) invalidArgument(std::string("filter '") + type() + "' has no image '" + name + "' (known: " + roleList(roles_) + ")");
  if (!view.ptr) {
    unsetImage(name);
    return;
  }
  const int c = view.channels();
  bool formatOk = role->isUint ? (view.format == Format::UInt || view.format == Format::Float)
                               : (view.format != Format::UInt && c >= role->minChannels && c <= role->maxChannels);
  if (!formatOk)
    invalidArgument("image '" + name + "': format " + formatName(view.format) + " not accepted (needs " +
                    acceptedFormats(*role) + ")");
  checkViewLayout("image '" + name + "'", view);
  auto it = images_.find(name);
  // Re-pointing a buffer of the same shape does not need a new commit.
  if (it == images_.end())
    markDirty("image '" + name + "' was set");
  else if (it->second.width != view.width || it->second.height != view.height || it->second.format != view.format)
    markDirty("image '" + name + "' was set to a new size or format");
  images_[name] = view;
}

void Filter::unsetImage(const std::string& name) {
  if (!findRole(roles_, name)) invalidArgument(std::string("filter '") + type() + "' has no image '" + name + "' (known: " + roleList(roles_) + ")");
  if (images_.erase(name)) markDirty("image '" + name + "' was unset");
}

bool Filter::hasImage(const std::string& name) const { return images_.count(name) != 0; }

const ImageView& Filter::image(const std::string& name) const {
  auto it = images_.find(name);
  if (it == images_.end()) invalidData(std::string("filter '") + type() + "': image '" + name + "' is not set");
  return it->second;
}

void Filter::commit() {
  commitFailed_ = true;  // until it returns
  for (const ImageRole& r : roles_)
    if (r.required && !hasImage(r.name))
      invalidData(std::string("filter '") + type() + "': required image '" + r.name + "' (" + r.meaning + ") is not set");
  const ImageView& color = image("color");
  for (const auto& [name, view] : images_)
    if (readsImage(name) && (view.width != color.width || view.height != color.height))
      invalidData("image '" + name + "' is " + std::to_string(view.width) + "x" + std::to_string(view.height) +
                  " but 'color' is " + std::to_string(color.width) + "x" + std::to_string(color.height));
  width_ = color.width;
  height_ = color.height;
  try {
    onCommit();
  } catch (const std::bad_alloc&) {  // say whose buffers and at what size, not a bare "out of memory"
    fail(CRISP_ERROR_OUT_OF_MEMORY, std::string("filter '") + type() + "': out of memory allocating its buffers for " +
                                        std::to_string(width_) + "x" + std::to_string(height_) + " images");
  }
  committed_ = true;
  everCommitted_ = true;
  commitFailed_ = false;
  firstChange_.clear();
}

void Filter::markDirty(const std::string& what) {
  if (firstChange_.empty()) firstChange_ = what;  // commit clears it: the first change since then
  committed_ = false;
}

void Filter::execute() {
  if (!committed_) {
    const std::string who = std::string("filter '") + type() + "': ";
    if (commitFailed_)
      fail(CRISP_ERROR_INVALID_OPERATION, who + "execute called after a commit that failed (see its error; fix it and commit again)");
    if (!everCommitted_) fail(CRISP_ERROR_INVALID_OPERATION, who + "execute called before commit");
    fail(CRISP_ERROR_INVALID_OPERATION,
         who + "execute called without a new commit after a change (" + firstChange_ + "; call commit again)");
  }
  try {
    onExecute();
  } catch (const std::bad_alloc&) {  // the first in-place run of a size copies the inputs the output overwrites
    fail(CRISP_ERROR_OUT_OF_MEMORY, std::string("filter '") + type() + "': out of memory filtering a " +
                                        std::to_string(width_) + "x" + std::to_string(height_) + " frame");
  }
}

std::string Filter::doc() const {
  std::ostringstream o;
  o << "Filter '" << type() << "'\n\nImages:\n\n| name | required | channels | meaning |\n|---|---|---|---|\n";
  for (const ImageRole& r : roles_)
    o << "| `" << r.name << "` | " << (r.required ? "yes" : "no") << " | "
      << (r.isUint ? std::string("uint id") : std::to_string(r.minChannels) + ".." + std::to_string(r.maxChannels))
      << " | " << r.meaning << " |\n";
  o << "\nParameters:\n\n" << params_.table();
  return o.str();
}

std::string Filter::infoJson() const {
  std::ostringstream o;
  o << "{\"type\": " << jsonQuote(type()) << ", \"images\": [";
  for (std::size_t i = 0; i < roles_.size(); ++i) {
    const ImageRole& r = roles_[i];
    o << (i ? ", " : "") << "{\"name\": " << jsonQuote(r.name) << ", \"required\": " << (r.required ? "true" : "false")
      << ", \"minChannels\": " << r.minChannels << ", \"maxChannels\": " << r.maxChannels
      << ", \"uint\": " << (r.isUint ? "true" : "false") << ", \"meaning\": " << jsonQuote(r.meaning) << "}";
  }
  o << "], \"params\": " << params_.json() << "}";
  return o.str();
}

ImageView Filter::inputApartFromOutput(const std::string& role) {
  const ImageView& in = image(role);
  if (!hasImage("output") || !viewsOverlap(in, image("output"))) return in;
  const std::size_t pixelBytes = formatBytes(in.format);
  std::vector<float>& copy = apartCopies_[role];
  copy.resize(std::size_t(in.width) * std::size_t(in.height) * (pixelBytes / 4));
  const ImageView packed = makeView(copy.data(), in.format, in.width, in.height);
  parallelRows(in.width, in.height, numThreads(), [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y)
      for (int x = 0; x < in.width; ++x) std::memcpy(packed.pixel(x, y), in.pixel(x, y), pixelBytes);
  });
  return packed;
}

void Filter::stageColor(Image& rgba) const {
  const ImageView& in = image("color");
  const int c = in.channels();
  parallelRows(width_, height_, numThreads(), [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      float* dst = rgba.at(0, y);
      for (int x = 0; x < width_; ++x, dst += 4) {
        const float* p = in.pixel(x, y);
        dst[0] = sanitizeColor(p[0]);
        dst[1] = sanitizeColor(c > 1 ? p[1] : p[0]);
        dst[2] = sanitizeColor(c > 2 ? p[2] : p[0]);
        dst[3] = c > 3 ? sanitizeColor(p[3]) : 1.0f;
      }
    }
  });
}

void Filter::writeOutput(const Image& rgba) const {
  const ImageView& out = image("output");
  const int c = out.channels();
  parallelRows(width_, height_, numThreads(), [&](int y0, int y1) {
    for (int y = y0; y < y1; ++y) {
      const float* src = rgba.at(0, y);
      for (int x = 0; x < width_; ++x, src += 4) {
        float* p = out.pixel(x, y);
        for (int k = 0; k < c; ++k) p[k] = src[k];
      }
    }
  });
}

}  // namespace crisp
