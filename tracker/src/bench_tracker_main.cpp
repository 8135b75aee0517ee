// ld-bench-tracker: the tracker's cost per frame, as a Markdown table.
#include <csignal>
#include <cstdio>
#include <vector>

#include <CLI/CLI.hpp>

#include "ld/cli.hpp"
#include "ld/tracker_bench.hpp"

int main(int argc, char** argv) {
  CLI::App app{"ld-bench-tracker: assignment and tracker update time by landmark count."};
  std::vector<int> counts{10, 50, 200};
  int repeats = 200;
  app.add_option("--landmarks", counts, "landmark counts, a list (1 to 1000 each)")
      ->delimiter(',')
      ->check(ld::cli::Between(1, 1000))
      ->capture_default_str();
  // (bounded: the timings are held, and repeats + 3 overflowed an int)
  app.add_option("--repeats", repeats, "timed runs per count, 1 to 1000000 (median reported)")
      ->check(ld::cli::Between(1, 1000000))->capture_default_str();
  LD_CLI_PARSE(app, argc, argv);
  // (a closed pipe is said, status 1, as a full disk is: not a silent
  // death by SIGPIPE after minutes of measuring)
  std::signal(SIGPIPE, SIG_IGN);

  std::printf("%s", ld::trackerTable(counts, repeats).c_str());
  return ld::cli::outputStatus(argv[0]);
}
