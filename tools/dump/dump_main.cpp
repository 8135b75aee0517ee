// ld-dump: the project's messages from log files or the live bus as JSON
// Lines, one object per message. Image payloads are summarised.
#include <atomic>
#include <csignal>
#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <iostream>
#include <regex>
#include <optional>
#include <set>

#include <CLI/CLI.hpp>
#include <lcm/lcm-cpp.hpp>

#include "ld/cli.hpp"
#include "ld/file_checks.hpp"
#include "ld/lcm_log_reader.hpp"
#include "ld/image_convert.hpp"
#include "ld/landmark_json.hpp"
#include "ld/landmark_msg.hpp"
#include "ld/lcm_url.hpp"
#include "ld/message_decode.hpp"
#include "ld/qr_code_list_t.hpp"

namespace {

std::atomic<bool> g_stop{false};
void onSignal(int) { g_stop = true; }

// Whether the bytes are a T; `why` says what was wrong with one that has T's
// fingerprint and does not decode (a damaged message of the project's).
template <typename T>
bool decodeAs(const uint8_t* data, size_t size, T& msg, std::string& why) {
  return ld::fingerprintOf(data, size) == T::getHash() && ld::decodeMessage(data, size, msg, &why);
}

nlohmann::ordered_json landmarkJson(const ld::landmark_t& m) {
  nlohmann::ordered_json j = ld::toJson(ld::fromMessage(m));
  j["score"] = std::round(m.score * 1000.0) / 1000.0;
  if (m.track_id >= 0) {
    j["track_id"] = m.track_id;
    j["age"] = m.age;
    j["frames_since_seen"] = m.frames_since_seen;
    j["time_since_seen_us"] = m.time_since_seen_us;
    j["visible"] = m.visible != 0;
  }
  return j;
}

// The JSON object of one message, or an "error" object when it is not one
// of the project's types or does not decode.
nlohmann::ordered_json toJson(const std::string& channel, int64_t log_utime, const uint8_t* data,
                      size_t size) {
  nlohmann::ordered_json j{{"channel", channel}};
  if (log_utime >= 0) j["log_utime"] = log_utime;
  ld::image_t img;
  ld::landmark_list_t list;
  ld::qr_code_list_t codes;
  std::string why;
  if (decodeAs(data, size, img, why)) {
    j["type"] = "image_t";
    j["utime"] = img.utime;
    j["seq"] = ld::imageSeq(img) ? nlohmann::ordered_json(*ld::imageSeq(img)) : nlohmann::ordered_json(nullptr);
    j["width"] = img.width;
    j["height"] = img.height;
    j["pixelformat"] = ld::pixelFormatName(img.pixelformat);
    j["row_stride"] = img.row_stride;
    j["size"] = img.size;
  } else if (decodeAs(data, size, list, why)) {
    j["type"] = "landmark_list_t";
    j["utime"] = list.utime;
    j["seq"] = list.seq;
    j["width"] = list.width;
    j["height"] = list.height;
    j["backend"] = list.backend;
    j["frames_skipped"] = list.frames_skipped;
    nlohmann::ordered_json stages = nlohmann::ordered_json::object();
    for (size_t i = 0; i < list.stage_names.size() && i < list.stage_ms.size(); ++i)
      stages[list.stage_names[i]] = std::round(list.stage_ms[i] * 1000.0) / 1000.0;
    j["stage_ms"] = stages;
    j["landmarks"] = nlohmann::ordered_json::array();
    for (const auto& m : list.landmarks) j["landmarks"].push_back(landmarkJson(m));
  } else if (decodeAs(data, size, codes, why)) {
    j["type"] = "qr_code_list_t";
    j["utime"] = codes.utime;
    j["seq"] = codes.seq;
    j["codes"] = nlohmann::ordered_json::array();
    for (const auto& c : codes.codes)
      j["codes"].push_back({{"track_id", c.track_id}, {"payload", c.payload}, {"utime", c.utime},
                            {"seq", c.seq}, {"decode_ms", c.decode_ms}});
    j["withheld_track_ids"] = codes.withheld_track_ids;
  } else {
    // (a fingerprint of an earlier version of a type: a recording by an
    // older build, said as such, not as another program's message)
    const std::string earlier = ld::earlierTypeVersion(data, size);
    j["error"] = !why.empty()      ? why
                 : earlier.empty() ? "not a project message (" + std::to_string(size) + " bytes)"
                                   : "an " + earlier + ", an earlier version no longer decoded (" +
                                         std::to_string(size) + " bytes; a recording by an older build?)";
  }
  return j;
}

struct Printer {
  std::vector<std::regex> filters;
  // (LCM's own self test, one message from each process as it opens LCM,
  // is no project message: left out unless a pattern asks for it; it was
  // printed first as "not a project message")
  bool wanted(const std::string& channel) const {
    if (filters.empty()) return channel != "LCM_SELF_TEST";
    for (const auto& f : filters)
      if (std::regex_match(channel, f)) return true;
    return false;
  }
  ld::QueueFit queue;  // (its subscription's: ld::QueueFit)
  int write_errno = 0;  // why the first write that failed did (LCM's calls after it set errno again)
  void onMessage(const lcm::ReceiveBuffer* rbuf, const std::string& channel) {
    queue.fit(rbuf->data_size);
    if (!wanted(channel) || !std::cout) return;
    errno = 0;
    std::cout << toJson(channel, -1, static_cast<const uint8_t*>(rbuf->data), rbuf->data_size)
                     .dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace)
              << std::endl;
    if (!std::cout && write_errno == 0) write_errno = errno ? errno : EIO;
  }
};

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"ld-dump: project messages from logs or the live bus as JSON Lines."};
  std::vector<std::string> logs, channels;
  std::string url = ld::defaultLcmUrl();
  bool live = false;
  app.add_option("logs", logs, "LCM log files (lcm-logger)");
  // (one pattern a -c: a list took the log files after it as patterns)
  app.add_option("-c,--channel", channels, "only channels matching this regex (repeatable)")->allow_extra_args(false);
  app.add_flag("--live", live, "read the live bus instead of files (Ctrl-C to stop)");
  app.add_option("--lcm-url", url, "LCM URL for --live")->capture_default_str();
  ld::LogSpan span;
  app.add_option("--from", span.from_s, "only messages logged this many seconds or more after each log's first")
      ->check(ld::cli::NonNegative);
  app.add_option("--to", span.to_s, "only messages logged at most this many seconds after each log's first")
      ->check(ld::cli::NonNegative);
  LD_CLI_PARSE(app, argc, argv);

  Printer printer;
  try {
    for (const auto& c : channels) printer.filters.emplace_back(c);
  } catch (const std::regex_error& e) {
    return ld::cli::usage(argv[0], std::string("bad channel pattern: ") + e.what());
  }
  if (live && !logs.empty()) return ld::cli::usage(argv[0], "give log files or --live, not both");
  if (!live && logs.empty()) return ld::cli::usage(argv[0], "give log files or --live");
  if (!live && app.count("--lcm-url"))
    return ld::cli::usage(argv[0], "--lcm-url is for --live (logs are read from their files)");
  if (live && span.limited())
    return ld::cli::usage(argv[0], "--from and --to are for logs (seconds after a log's first message)");
  if (const std::string problem = span.problem(); !problem.empty()) return ld::cli::usage(argv[0], problem);
  if (live) {
    if (!ld::lcmUrlUsable(url, "ld-dump")) return 2;
    lcm::LCM lcm(url);
    if (const int status = ld::lcmOpenStatus(lcm, url, "ld-dump")) return status;
    printer.queue = ld::QueueFit(lcm.subscribe(".*", &Printer::onMessage, &printer));
    std::signal(SIGINT, onSignal);
    std::signal(SIGTERM, onSignal);
    // (output that cannot be written, a full disk, ends the dump, said:
    // it ran on and said nothing)
    while (!g_stop && lcm.handleTimeout(200) >= 0 && std::cout) {
    }
    if (!std::cout || !std::cout.flush()) {
      std::cerr << "ld-dump: write to stdout failed: "
                << std::strerror(printer.write_errno ? printer.write_errno : errno ? errno : EIO) << "\n";
      return 1;
    }
    return 0;
  }
  // Exit status: 2 when a file is not an LCM log or cannot be read at all
  // (missing, a folder, no permission: as ld-run and ld-play refuse it),
  // else 1 when a log was read only in part, else 0.
  int status = 0;
  int64_t printed = 0;
  std::set<std::string> seen_channels;
  double longest_s = 0;  // (the longest log's span, said where --from/--to took nothing)
  for (const auto& path : logs) {
    const ld::LcmLogCheck start = ld::checkLcmLogStart(path);
    if (start.start == ld::LcmLogStart::NotALog) {
      std::cerr << "ld-dump: " << path << " " << start.problem << "\n";
      status = 2;
      continue;
    }
    if (start.start == ld::LcmLogStart::Empty) continue;  // a recorder that recorded nothing
    // (said before the log is opened: opening a pipe waited for a writer for ever)
    std::optional<ld::LcmLogReader> log;
    if (start.start != ld::LcmLogStart::Unreadable) log.emplace(path);
    if (!log || !log->good()) {
      std::cerr << "ld-dump: cannot read log " << path << ": "
                << (start.error.empty() ? std::strerror(errno) : start.error) << "\n";
      status = 2;
      continue;
    }
    int64_t first = -1;
    while (log->next()) {
      seen_channels.insert(log->channel);
      if (first < 0) first = log->timestamp;
      longest_s = std::max(longest_s, static_cast<double>(log->timestamp - first) / 1e6);
      if (!span.holds(first, log->timestamp)) continue;
      if (!printer.wanted(log->channel)) continue;
      ++printed;
      std::cout << toJson(log->channel, log->timestamp, log->data.data(), log->data.size())
                       .dump(-1, ' ', false, nlohmann::ordered_json::error_handler_t::replace)
                << "\n";
    }
    if (!log->problem().empty()) {
      std::cout << std::flush;
      std::cerr << "ld-dump: " << path << ": " << log->problem() << "\n";
      status = std::max(status, 1);
    }
  }
  // (a -c that matches no channel is said as such, span or not: a
  // misspelt channel was blamed on the span)
  const bool some_channel_wanted =
      std::any_of(seen_channels.begin(), seen_channels.end(), [&](const std::string& c) { return printer.wanted(c); });
  if (span.limited() && printed == 0 && some_channel_wanted) {
    char longest[32];
    std::snprintf(longest, sizeof longest, "%g", std::round(longest_s * 1000) / 1000);
    std::cerr << "ld-dump: note: no message" << (channels.empty() ? "" : " of the channels asked for") << " "
              << span.text() << " after a log's first (the longest log spans " << longest << " s)\n";
  } else if (!channels.empty() && printed == 0 && !seen_channels.empty() && !some_channel_wanted) {
    std::string names;
    for (const auto& c : seen_channels) names += (names.empty() ? "" : ", ") + c;
    std::cerr << "ld-dump: note: no channel of the logs matches -c (a pattern matches the whole name, "
                 "case and all); their channels: " << names << "\n";
  }
  if (!std::cout.flush()) {  // (a full disk: the dump is not all there)
    std::cerr << "ld-dump: write to stdout failed: " << std::strerror(errno) << "\n";
    return std::max(status, 1);
  }
  return status;
}
