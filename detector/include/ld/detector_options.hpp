// The detector's command-line options, shared by ld-detect and ld-detector:
// --params, --camera, --size, --backend, --adaptive.
#pragma once

#include <string>

#include <CLI/CLI.hpp>

#include "ld/adaptive.hpp"
#include "ld/detector.hpp"

namespace ld {

struct DetectorOptions {
  std::string params_file, camera_file, backend;
  double side_m = 0;
  bool adaptive = false;  ///< an ld::LightingAdapter in front of the detector

  /// Adds the options to `app`.
  void addTo(CLI::App& app);

  /// The detector the options describe (parameters file, backend override,
  /// camera and side for pose). Throws std::exception with a message naming
  /// what is wrong (a bad file, an unavailable backend, pose with only one
  /// of --camera and --size).
  Detector make() const;
  /// The same, with the lighting adapter in front when --adaptive was given.
  AdaptiveDetector makeAdaptive() const;
};

}  // namespace ld
