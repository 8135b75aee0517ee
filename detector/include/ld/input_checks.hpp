// The checks every library makes of what its caller hands it: an image of a
// type it reads, a parameter within its range. Each says, in a
// std::invalid_argument naming the caller's function or parameter set,
// what a wrong value would otherwise have done without a word.
#pragma once

#include <iomanip>
#include <sstream>
#include <stdexcept>
#include <string>

#include <opencv2/core.hpp>

namespace ld {

/// Throws std::invalid_argument ("WHO: a CV_16UC3 image: it reads 8-bit BGR,
/// BGRA or gray (...)") for an image that is neither empty nor 8-bit with 1,
/// 3 or 4 channels (a 16-bit PNG read with IMREAD_UNCHANGED found nothing).
inline void requireReadableImage(const cv::Mat& image, const char* who) {
  if (image.empty() || (image.dims == 2 && image.depth() == CV_8U &&
                        (image.channels() == 1 || image.channels() == 3 || image.channels() == 4)))
    return;
  // (a matrix of 3 or more dimensions has no rows and columns to read: it
  // gave no landmarks without a word)
  if (image.dims != 2)
    throw std::invalid_argument(std::string(who) + ": a matrix of " + std::to_string(image.dims) +
                                " dimensions: it reads 2-dimensional 8-bit BGR, BGRA or gray images");
  throw std::invalid_argument(std::string(who) + ": a " + cv::typeToString(image.type()) +
                              " image: it reads 8-bit BGR, BGRA or gray (CV_8UC3, CV_8UC4, CV_8UC1)");
}

/// Throws std::invalid_argument ("OWNER: NAME must be LO to HI, not V")
/// unless lo <= v <= hi; NaN is never within.
inline void requireWithin(const char* owner, const char* name, double v, double lo, double hi) {
  if (v >= lo && v <= hi) return;
  std::ostringstream s;
  s << std::setprecision(10) << owner << ": " << name << " must be " << lo << " to " << hi << ", not " << v;
  throw std::invalid_argument(s.str());
}

}  // namespace ld
