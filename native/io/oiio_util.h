// SPDX-License-Identifier: Apache-2.0
// OpenImageIO error handling shared by the reader and the writer. OIIO keeps
// errors per object and in a per-thread global queue; unread messages would
// leak into the next call (and are printed at exit), so every call drains both.
#pragma once

#include <string>

#include <OpenImageIO/imageio.h>

namespace crisp {

// Takes and clears the messages of `object` (ImageInput/ImageOutput, may be
// null) and of OIIO's global queue, joined on one line.
template <class OiioObject>
std::string oiioErrors(OiioObject* object) {
  std::string message;
  if (object && object->has_error()) message = object->geterror();
  std::string global = OIIO::geterror();
  if (!global.empty()) message += (message.empty() ? "" : "; ") + global;
  for (char& c : message)
    if (c == '\n') c = ' ';
  while (!message.empty() && message.back() == ' ') message.pop_back();
  return message.empty() ? std::string("unknown OpenImageIO error") : message;
}
inline std::string oiioErrors(std::nullptr_t) { return oiioErrors(static_cast<OIIO::ImageInput*>(nullptr)); }

// Clears OIIO's global error queue when leaving a scope, however it is left.
struct OiioErrorDrain {
  OiioErrorDrain() { OIIO::geterror(); }
  ~OiioErrorDrain() { OIIO::geterror(); }
  OiioErrorDrain(const OiioErrorDrain&) = delete;
  OiioErrorDrain& operator=(const OiioErrorDrain&) = delete;
};

}  // namespace crisp
