// Fuzz target: ld-run's config reader, RunConfig::load (ld-run --config),
// JSON and YAML.
//
// Byte 0 picks the format (even: YAML, odd: JSON); the rest is the file. A
// file either loads or throws std::runtime_error naming the problem (any
// other exception escapes and is a finding); a config that loads must then
// give its process table, or a std::runtime_error saying why it cannot.
#include <cstdint>
#include <stdexcept>

#include "fuzz_file.hpp"
#include "ld/run_config.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  if (size < 1) return 0;
  const std::string path = ld::fuzz::writeInput(data + 1, size - 1, data[0] % 2 == 0 ? ".yaml" : ".json");
  try {
    const ld::RunConfig cfg = ld::RunConfig::load(path);
    (void)ld::buildProcessSpecs(cfg, "udpm://239.255.76.67:7667?ttl=0", "/nonexistent");
  } catch (const std::runtime_error&) {
  }
  return 0;
}
