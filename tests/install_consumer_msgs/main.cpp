// Encodes a tracked landmark list with the installed message headers,
// decodes it again and prints what came back: "<seq> <track id> <payload>
// <TL corner x> <TL corner y>".
#include <cstdio>
#include <vector>

#include "ld/landmark_list_t.hpp"

int main() {
  ld::landmark_list_t list{};
  list.utime = 123456;
  list.seq = 7;
  list.backend = "tracker";
  list.nlandmarks = 1;
  list.landmarks.resize(1);
  list.landmarks[0].track_id = 42;
  list.landmarks[0].has_payload = true;
  list.landmarks[0].payload = "dock";
  list.landmarks[0].corners[0][0] = 10.5f;
  list.landmarks[0].corners[0][1] = 20.25f;
  std::vector<char> buf(static_cast<size_t>(list.getEncodedSize()));
  if (list.encode(buf.data(), 0, static_cast<int>(buf.size())) < 0) return 1;
  ld::landmark_list_t back;
  if (back.decode(buf.data(), 0, static_cast<int>(buf.size())) < 0 || back.nlandmarks != 1) return 1;
  const ld::landmark_t& l = back.landmarks[0];
  std::printf("%lld %lld %s %g %g\n", static_cast<long long>(back.seq), static_cast<long long>(l.track_id),
              l.payload.c_str(), l.corners[0][0], l.corners[0][1]);
  return 0;
}
