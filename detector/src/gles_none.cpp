// Builds without OpenGL ES (no EGL or GLESv2 development files found by
// CMake, or LD_WITH_GLES=OFF): the GLES backend is never available, and
// "auto" runs the CPU backend.
#include "filters.hpp"

namespace ld::detail {

bool glesBuilt() { return false; }

std::unique_ptr<Filters> makeGlesFilters(std::string& why, bool, bool) {
  why = "this build has no GLES backend (EGL/GLESv2 development files missing at configure time)";
  return nullptr;
}

}  // namespace ld::detail
