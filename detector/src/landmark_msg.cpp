#include "ld/landmark_msg.hpp"
#include "ld/message_publisher.hpp"

namespace ld {
namespace {

void put(float dst[2], const cv::Point2f& p) {
  dst[0] = p.x;
  dst[1] = p.y;
}

cv::Point2f get(const float src[2]) { return {src[0], src[1]}; }

}  // namespace

landmark_t toMessage(const Landmark& lm) {
  landmark_t m{};
  put(m.fip_tl, lm.fip_tl);
  put(m.fip_tr, lm.fip_tr);
  put(m.fip_bl, lm.fip_bl);
  put(m.ap, lm.ap);
  for (size_t i = 0; i < 4; ++i) put(m.corners[i], lm.corners[i]);
  m.score = lm.score;
  m.has_payload = lm.payload.has_value();
  m.payload = ld::lcmString(lm.payload.value_or(""));  // (a NUL byte: U+FFFD)
  m.pose_valid = lm.pose.has_value();
  if (lm.pose) {
    for (int i = 0; i < 3; ++i) {
      m.t[i] = lm.pose->t[i];
      m.rvec[i] = lm.pose->rvec[i];
    }
    m.distance = lm.pose->distance;
  }
  m.track_id = -1;
  m.visible = true;
  return m;
}

Landmark fromMessage(const landmark_t& m) {
  Landmark lm;
  lm.fip_tl = get(m.fip_tl);
  lm.fip_tr = get(m.fip_tr);
  lm.fip_bl = get(m.fip_bl);
  lm.ap = get(m.ap);
  for (size_t i = 0; i < 4; ++i) lm.corners[i] = get(m.corners[i]);
  lm.score = m.score;
  if (m.has_payload) lm.payload = m.payload;
  if (m.pose_valid) lm.pose = Pose{{m.t[0], m.t[1], m.t[2]}, {m.rvec[0], m.rvec[1], m.rvec[2]}, m.distance};
  return lm;
}

void toListMessage(const Detection& det, int64_t utime, int64_t seq, int width, int height,
                   const std::string& backend, int64_t frames_skipped, landmark_list_t& out) {
  out.utime = utime;
  out.seq = seq;
  out.width = width;
  out.height = height;
  out.backend = backend;
  out.frames_skipped = frames_skipped;
  out.nstages = static_cast<int32_t>(det.stages.size());
  out.stage_names.resize(det.stages.size());
  out.stage_ms.resize(det.stages.size());
  for (size_t i = 0; i < det.stages.size(); ++i) {
    out.stage_names[i] = det.stages[i].name;
    out.stage_ms[i] = static_cast<float>(det.stages[i].ms);
  }
  out.nlandmarks = static_cast<int32_t>(det.landmarks.size());
  out.landmarks.resize(det.landmarks.size());
  for (size_t i = 0; i < det.landmarks.size(); ++i) out.landmarks[i] = toMessage(det.landmarks[i]);
}

}  // namespace ld
