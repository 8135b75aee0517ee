// Fuzz target: the parameter file readers, DetectorParams::load (ld-detector
// --params) and TrackerParams::load (ld-tracker --params).
//
// Byte 0 picks the reader (even: detector, odd: tracker); the rest is the
// file. A file either loads or throws std::exception naming the problem;
// parameters that load and validate must then run: the detector on a frame
// with a landmark, the tracker on two frames of two landmarks.
#include <cstdint>
#include <optional>
#include <stdexcept>

#include "fuzz_file.hpp"
#include "ld/detector.hpp"
#include "ld/tracker.hpp"
#include "synth_frame.hpp"

namespace {

// The parameters in the file, when they load and validate (a clear error
// otherwise is what the target checks for: no crash, no hang).
template <typename Params>
std::optional<Params> loadValid(const std::string& path) {
  try {
    Params p = Params::load(path);
    p.validate();
    return p;
  } catch (const std::runtime_error&) {
  } catch (const std::invalid_argument&) {
  }
  return std::nullopt;
}

void detectorParams(const std::string& path) {
  const auto p = loadValid<ld::DetectorParams>(path);
  if (!p) return;
  ld::Detector detector(*p);
  (void)detector.detect(ld::fuzz::landmarkFrame());
}

void trackerParams(const std::string& path) {
  const auto p = loadValid<ld::TrackerParams>(path);
  if (!p) return;
  ld::Tracker tracker(*p);
  std::vector<ld::Landmark> dets(2);
  for (size_t i = 0; i < dets.size(); ++i) {
    const float x = 40.0f + 60.0f * static_cast<float>(i), y = 50.0f;
    dets[i].fip_tl = {x, y};
    dets[i].fip_tr = {x + 20, y};
    dets[i].fip_bl = {x, y + 20};
    dets[i].ap = {x + 20, y + 20};
    dets[i].corners = {{{x - 5, y - 5}, {x + 25, y - 5}, {x + 25, y + 25}, {x - 5, y + 25}}};
  }
  (void)tracker.update(dets, 1000000);
  for (auto& d : dets) d.fip_tl.x += 2;
  (void)tracker.update({dets[0]}, 1033333);
  (void)tracker.update({}, 9000000);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string path = ld::fuzz::writeInput(data + 1, size - 1, ".yml");
  if (data[0] % 2 == 0) detectorParams(path);
  else trackerParams(path);
  return 0;
}
