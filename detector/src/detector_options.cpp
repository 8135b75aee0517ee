#include "ld/detector_options.hpp"

#include <optional>
#include <stdexcept>

#include "ld/cli.hpp"

namespace ld {

void DetectorOptions::addTo(CLI::App& app) {
  app.add_option("--params", params_file, "detector parameters (YAML)");
  CLI::Option* camera = app.add_option(
      "--camera", camera_file,
      "camera calibration (OpenCV YAML/XML, ROS camera_info, opencv_interactive-calibration), for pose");
  CLI::Option* size =
      app.add_option("--size", side_m, "printed landmark side S in metres, for pose (0.01 to 10)")
          ->check(cli::Between(0.01, 10.0));
  // pose needs both
  size->needs(camera);
  camera->needs(size);
  app.add_option("--backend", backend,
                 "where the filters run: cpu; gles (OpenGL ES on a headless EGL context, an error when none "
                 "can be made; Mesa's llvmpipe counts); auto (a GPU when there is one, else the CPU with one "
                 "warning). Default: the params file's, else cpu")
      ->check(CLI::IsMember({"cpu", "gles", "auto"}));
  app.add_flag("--adaptive", adaptive,
               "adapt to the light's colour and level (white balance from confirmed landmarks' sheets or "
               "the frame's whitest pixels) before detecting");
}

Detector DetectorOptions::make() const {
  DetectorParams params;
  if (!params_file.empty()) params = DetectorParams::load(params_file);
  if (!backend.empty()) params.backend = backend;
  params.validate();
  // Both files read before the detector starts the GPU's threads (a file is
  // parsed in a child process first: ld::parserFailure), and a bad pose
  // option refused before any of it.
  std::optional<CameraModel> camera;
  if (!camera_file.empty() || side_m > 0) {
    if (camera_file.empty()) throw std::invalid_argument("--size without --camera: pose needs both");
    if (side_m <= 0) throw std::invalid_argument("--camera without --size: pose needs both");
    camera = CameraModel::load(camera_file);
  }
  Detector detector(params);
  if (camera) detector.setCamera(*camera, side_m);
  return detector;
}

AdaptiveDetector DetectorOptions::makeAdaptive() const { return AdaptiveDetector(make(), adaptive); }

}  // namespace ld
