// Test helper: what ld::imageToBgr says about an IMAGE message.
#pragma once

#include <string>

#include "ld/image_convert.hpp"

namespace ld::test {

/// The message of the ld::ImageFormatError that converting `msg` throws, or
/// "" when it converts.
inline std::string imageError(const image_t& msg) {
  try {
    imageToBgr(msg);
  } catch (const ImageFormatError& e) {
    return e.what();
  }
  return "";
}

}  // namespace ld::test
