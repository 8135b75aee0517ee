#include "ld/file_checks.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <vector>

#include <signal.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <opencv2/imgcodecs.hpp>

#include "ld/image_convert.hpp"

namespace ld {

namespace {
// "ed a1 da 01": a file's first bytes (at most 4) as a message shows them.
std::string hexStart(const unsigned char* bytes, size_t n) {
  std::string start;
  char hex[4];
  for (size_t i = 0; i < 4 && i < n; ++i) {
    std::snprintf(hex, sizeof hex, "%02x", bytes[i]);
    start += (i ? " " : "") + std::string(hex);
  }
  return start;
}
}  // namespace

LcmLogCheck checkLcmLogStart(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const auto unreadable = [](const std::string& error) {
    return LcmLogCheck{LcmLogStart::Unreadable, "cannot be read: " + error, error};
  };
  if (fs::is_directory(path, ec)) return unreadable("it is a folder");
  // (a pipe, as `<(cat run.lcmlog)` gives, was read here and then again
  // from where this read stopped: "cannot read log /dev/fd/63", no reason;
  // the tools read a log from its start more than once)
  struct stat st {};
  if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
    return unreadable("it is not a file (a pipe, a device?): logs are read from files");
  std::ifstream f(path, std::ios::binary);
  if (!f) return unreadable(std::strerror(errno));
  unsigned char head[kLcmLogHeaderBytes];
  f.read(reinterpret_cast<char*>(head), sizeof head);
  const size_t got = static_cast<size_t>(f.gcount());
  if (got == 0) {
    if (f.bad()) return unreadable(std::strerror(errno));
    return {LcmLogStart::Empty, "is empty", ""};
  }
  // (a log cut within its magic, 1 to 3 bytes of it, is a log cut short,
  // not another file)
  bool magic_so_far = true;
  for (size_t i = 0; i < 4 && i < got; ++i)
    magic_so_far = magic_so_far && head[i] == ((kLcmLogMagic >> (8 * (3 - i))) & 0xffu);
  if (!magic_so_far)
    return {LcmLogStart::NotALog,
            "is not an LCM log (it starts with " + hexStart(head, got) + ", not LCM's event magic ed a1 da 01)", ""};
  if (got < kLcmLogHeaderBytes)
    return {LcmLogStart::CutInHeader, "ends inside its first event header (" + std::to_string(got) + " of " +
                                          std::to_string(kLcmLogHeaderBytes) + " bytes)", ""};
  return {LcmLogStart::Events, "", ""};
}

std::string prepareOutputFolder(const std::string& folder) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_directory(folder, ec)) {
    fs::create_directories(folder, ec);
    if (ec) return "cannot create folder " + folder + ": " + ec.message();
  }
  // access() says yes to root on any folder; creating a file is the test.
  std::string probe = (fs::path(folder) / ".ld-write-test-XXXXXX").string();
  const int fd = ::mkstemp(probe.data());
  if (fd < 0) {
    // (a folder of a virtual file system, /proc or /sys, answers "No such
    // file or directory" for a file it will not create)
    const int err = errno;
    return "cannot write in folder " + folder + ": " +
           (err == ENOENT ? std::string("files cannot be created there") : std::strerror(err));
  }
  ::close(fd);
  ::unlink(probe.c_str());
  return "";
}

std::string prepareOutputFile(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (path.empty()) return "is an empty path";
  if (fs::is_directory(path, ec)) return "is a folder";
  if (path.back() == '/') return "names a folder (it ends in /), not a file";
  // (a name the file system cannot hold: the run went on, and failed to
  // write at its end; the folder's own limit, 255 bytes on most)
  const std::string name = fs::path(path).filename().string();
  const fs::path folder = fs::path(path).parent_path();
  const long name_max = ::pathconf(folder.empty() ? "." : folder.c_str(), _PC_NAME_MAX);
  if (static_cast<long>(name.size()) > (name_max > 0 ? name_max : 255))
    return "has a name of " + std::to_string(name.size()) + " bytes, more than the " +
           std::to_string(name_max > 0 ? name_max : 255) + " a file name may have here";
  if (std::string problem = prepareOutputFolder(folder.empty() ? "." : folder.string()); !problem.empty())
    return problem;
  if (fs::exists(path, ec) && ::access(path.c_str(), W_OK) != 0)
    return std::string("cannot be written: ") + std::strerror(errno);
  return "";
}

CaughtStderr::CaughtStderr() {
  file_ = ::memfd_create("ld-caught-stderr", MFD_CLOEXEC);
  if (file_ < 0) return;
  std::fflush(stderr);
  saved_ = ::dup(STDERR_FILENO);
  if (saved_ < 0 || ::dup2(file_, STDERR_FILENO) < 0) restore();
}

CaughtStderr::~CaughtStderr() {
  restore();
  if (file_ >= 0) ::close(file_);
}

void CaughtStderr::restore() {
  if (saved_ >= 0) {
    std::fflush(stderr);
    ::dup2(saved_, STDERR_FILENO);
    ::close(saved_);
    saved_ = -1;
  }
}

std::string CaughtStderr::end() {
  restore();
  if (file_ < 0) return "";
  // (all of it: the error libpng ends with may follow many warnings)
  std::string text;
  struct stat st {};
  if (::fstat(file_, &st) == 0 && st.st_size > 0) {
    text.resize(static_cast<size_t>(std::min<off_t>(st.st_size, off_t{16} << 20)));
    size_t got = 0;
    while (got < text.size()) {
      const ssize_t n = ::pread(file_, text.data() + got, text.size() - got, static_cast<off_t>(got));
      if (n <= 0) break;
      got += static_cast<size_t>(n);
    }
    text.resize(got);
  }
  ::close(file_);
  file_ = -1;
  std::string said;
  size_t at = 0;
  while (at < text.size()) {
    size_t end = text.find('\n', at);
    if (end == std::string::npos) end = text.size();
    std::string line = text.substr(at, end - at);
    at = end + 1;
    line.erase(std::remove_if(line.begin(), line.end(), [](char c) { return static_cast<unsigned char>(c) < 0x20; }),
               line.end());
    if (line.empty() || line.find("warning") != std::string::npos) continue;
    said += (said.empty() ? "" : "; ") + line;
  }
  constexpr size_t kMaxSaid = 1000;  // (one line, however much was printed)
  if (said.size() > kMaxSaid) said = said.substr(0, kMaxSaid) + "...";
  return said;
}

int64_t aviVideoFrames(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) return -1;
  f.seekg(0, std::ios::end);
  const int64_t end = static_cast<int64_t>(f.tellg());
  const auto read = [&f](int64_t at, char* out, std::streamsize n) {
    f.clear();
    f.seekg(at);
    return static_cast<bool>(f.read(out, n));
  };
  const auto u32 = [](const char* p) {
    return static_cast<int64_t>(static_cast<uint8_t>(p[0])) | static_cast<int64_t>(static_cast<uint8_t>(p[1])) << 8 |
           static_cast<int64_t>(static_cast<uint8_t>(p[2])) << 16 | static_cast<int64_t>(static_cast<uint8_t>(p[3])) << 24;
  };
  // The chunks of [from, to): lists walked into, frames counted in the
  // 'movi' lists (and the 'rec ' lists within them), other chunks stepped over.
  int64_t frames = 0;
  // (lists nest 3 deep in an AVI: deeper is no AVI's, and not followed)
  const std::function<void(int64_t, int64_t, bool, int)> walk = [&](int64_t from, int64_t to, bool movi, int depth) {
    if (depth > 8) return;
    char h[12];
    for (int64_t at = from; at + 8 <= to;) {
      if (!read(at, h, 8)) return;
      const int64_t size = u32(h + 4);
      const int64_t data_end = at + 8 + size;
      const bool is_list = std::memcmp(h, "LIST", 4) == 0;
      // (a chunk cut short ends the count; a list, whose size was written
      // for what it was to hold, is walked as far as the file goes)
      if (data_end > end && !is_list) return;
      if (is_list && size >= 4 && read(at + 8, h + 8, 4))
        walk(at + 12, std::min(data_end, end), movi || std::memcmp(h + 8, "movi", 4) == 0,
             depth + 1);  // (and 'rec ' in it)
      else if (movi && (std::memcmp(h + 2, "dc", 2) == 0 || std::memcmp(h + 2, "db", 2) == 0))
        ++frames;
      at = data_end + (size & 1);
    }
  };
  char h[12];
  bool avi = false;
  for (int64_t at = 0; at + 12 <= end;) {
    if (!read(at, h, 12) || std::memcmp(h, "RIFF", 4) != 0) break;
    const bool first = at == 0;
    if (first && std::memcmp(h + 8, "AVI ", 4) != 0) return -1;
    if (!first && std::memcmp(h + 8, "AVIX", 4) != 0) break;
    avi = true;
    // (a RIFF size the writer left unset or too large: the file's end)
    const int64_t size = u32(h + 4);
    const int64_t section_end = size >= 4 && at + 8 + size <= end ? at + 8 + size : end;
    walk(at + 12, section_end, false, 0);
    at = section_end + (section_end & 1);
  }
  return avi ? frames : -1;
}

namespace {
constexpr const char* kImageExtensions[] = {".png", ".jpg", ".jpeg", ".jpe",  ".jfif", ".bmp", ".ppm",
                                            ".pgm", ".pbm", ".pnm",  ".tif",  ".tiff", ".webp", ".jp2",
                                            ".hdr", ".pic", ".sr",   ".ras",  ".exr",  ".pfm"};
// Image kinds OpenCV does not read (Debian's 4.6): said when a folder holds them.
constexpr const char* kUnreadExtensions[] = {".heic", ".heif", ".hif", ".avif", ".gif", ".dng", ".cr2",
                                             ".cr3",  ".nef",  ".arw", ".orf",  ".rw2", ".raf"};

// Whether the path's extension, in any case, is one of `extensions`.
template <size_t N>
bool hasExtension(const std::filesystem::path& p, const char* const (&extensions)[N]) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return std::any_of(std::begin(extensions), std::end(extensions), [&](const char* e) { return ext == e; });
}
}  // namespace

bool isImageFileName(const std::filesystem::path& path) { return hasExtension(path, kImageExtensions); }

std::string imageFileExtensions() {
  std::string out;
  for (const char* e : kImageExtensions) out += (out.empty() ? "" : ", ") + std::string(e);
  return out;
}

std::string listImageFolder(const std::string& dir, std::vector<std::string>& files, std::vector<std::string>& unread) {
  files.clear();
  unread.clear();
  std::error_code ec;
  std::filesystem::directory_iterator it(dir, ec);
  if (ec) return ec.message();
  for (; it != std::filesystem::directory_iterator(); it.increment(ec)) {
    if (ec) return ec.message();
    const std::filesystem::path& p = it->path();
    std::error_code is_dir_ec;
    if (it->is_directory(is_dir_ec)) continue;
    if (isImageFileName(p)) files.push_back(p.string());
    else if (hasExtension(p, kUnreadExtensions)) unread.push_back(p.filename().string());
  }
  if (ec) return ec.message();
  std::sort(files.begin(), files.end());
  std::sort(unread.begin(), unread.end());
  return "";
}

std::string describeUnreadImages(const std::vector<std::string>& unread) {
  if (unread.empty()) return "";
  std::string names;
  for (size_t i = 0; i < unread.size() && i < 3; ++i) names += (i ? ", " : "") + unread[i];
  if (unread.size() > 3) names += ", ...";
  return std::to_string(unread.size()) + (unread.size() == 1 ? " file" : " files") +
         " of image kinds OpenCV does not read (HEIC/HEIF, AVIF, GIF, camera raw) left out (" + names +
         "): convert them to JPEG or PNG";
}

namespace {
// The turn that makes `stored` into `shown` (ImageTurn), if any, from a grid
// of their pixels (up to 48 x 48, each compared with the stored pixel the
// turn puts there): a few thousand pixels, where turning the whole of a
// 12 MP photo for each of the eight took a second.
bool findTurn(const cv::Mat& stored, const cv::Mat& shown, ImageTurn& turn) {
  if (stored.type() != CV_8UC3 || shown.type() != CV_8UC3) return false;
  const int step_x = std::max(1, shown.cols / 48), step_y = std::max(1, shown.rows / 48);
  for (bool mirrored : {false, true})
    for (int k = 0; k < 4; ++k) {
      if ((k % 2 ? cv::Size(stored.rows, stored.cols) : stored.size()) != shown.size()) continue;
      bool same = true;
      for (int v = 0; v < shown.rows && same; v += step_y)
        for (int u = 0; u < shown.cols && same; u += step_x) {
          // undo the quarter turns clockwise, then the mirror: (u, v) in a
          // w x h image came from (v, w - 1 - u) in the h x w one before
          int x = u, y = v, w = shown.cols, h = shown.rows;
          for (int q = 0; q < k; ++q) {
            const int px = y, py = w - 1 - x;
            x = px, y = py;
            std::swap(w, h);
          }
          if (mirrored) x = w - 1 - x;
          same = stored.at<cv::Vec3b>(y, x) == shown.at<cv::Vec3b>(v, u);
        }
      // (a grid can miss what tells two turns apart in a flat picture: the
      // candidate is confirmed on every pixel, one turn of the image)
      if (same) {
        cv::Mat flipped, turned;
        if (mirrored) cv::flip(stored, flipped, 1);
        const cv::Mat& from = mirrored ? flipped : stored;
        if (k) cv::rotate(from, turned, k == 1 ? cv::ROTATE_90_CLOCKWISE : k == 2 ? cv::ROTATE_180
                                                                                 : cv::ROTATE_90_COUNTERCLOCKWISE);
        same = cv::norm(k ? turned : from, shown, cv::NORM_INF) == 0;
      }
      if (same) {
        turn.quarter_turns_cw = k;
        turn.mirrored = mirrored;
        return true;
      }
    }
  return false;
}

// readImageFile, and the turn where `turn` is given.
std::string readImage(const std::string& path, cv::Mat& out, ImageTurn* turn) {
  if (turn) *turn = ImageTurn{};
  out.release();
  constexpr off_t kMaxImageFile = off_t{512} << 20;
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)
    return errno == ENOENT ? "no such file"
           : errno == ELOOP ? "is a loop of symbolic links"
                            : std::string("cannot read: ") + std::strerror(errno);
  if (!S_ISREG(st.st_mode)) return "is not a file (a pipe, a device?)";
  if (st.st_size == 0) return "is empty (0 bytes: a copy or a download that failed?)";
  if (st.st_size > kMaxImageFile)
    return "is " + std::to_string(st.st_size >> 20) + " MiB: more than an image file has (512 MiB at most)";
  std::ifstream f(path, std::ios::binary);
  std::vector<uint8_t> bytes(static_cast<size_t>(st.st_size));
  if (!f || !f.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size())))
    return std::string("cannot read: ") + std::strerror(errno ? errno : EIO);
  cv::Mat stored;  // (a JPEG's pixels as stored, where OpenCV may turn them)
  if (bytes.size() >= 3 && bytes[0] == 0xFF && bytes[1] == 0xD8 && bytes[2] == 0xFF) {
    if (!jpegComplete(bytes.data(), bytes.size()))
      return "cannot read as an image: it is a JPEG cut short (no end-of-image marker)";
    // (damaged data: libjpeg fills it with grey, and said so on stderr alone;
    // up to 2^30 pixels, as OpenCV's own limit)
    std::string damage;
    try {
      damage = decodeJpeg(bytes.data(), bytes.size(), out);
    } catch (const std::exception& e) {
      damage = std::string("could not be decoded (") + e.what() + ")";
    }
    if (!damage.empty()) {
      out.release();
      return "cannot read as an image: it is a JPEG that " + damage;
    }
    // (OpenCV's image, decoded once: the decode below is for a JPEG that
    // OpenCV turns as its Exif orientation says, or a CMYK one)
    if (jpegReadsAsDecoded(bytes.data(), bytes.size())) {
      if (turn) turn->stored = out.size();
      return "";
    }
    if (turn) stored = std::move(out);  // (to tell how OpenCV turns it, where asked)
    out.release();
  }
  // A floating-point image (PFM, OpenEXR; a TIFF of floats) came out black
  // or wrong: OpenCV turns its values, 0 to 1, into 8 bits without scaling.
  // What a float means (linear light, its range) is the file's maker's to
  // say: refused, named. (Radiance HDR OpenCV scales itself: it reads.)
  const auto starts = [&](const char* magic, size_t n) {
    return bytes.size() >= n && std::memcmp(bytes.data(), magic, n) == 0;
  };
  std::string floating;
  if ((starts("PF", 2) || starts("Pf", 2)) && bytes.size() > 2 && std::isspace(bytes[2])) floating = "a PFM image";
  else if (starts("\x76\x2f\x31\x01", 4)) floating = "an OpenEXR image";
  else if (starts("II*\0", 4) || starts("MM\0*", 4) || starts("II+\0", 4) || starts("MM\0+", 4)) {
    cv::Mat probe;  // (a TIFF says its sample format deep in its tags: OpenCV reads them)
    CaughtStderr tiff_said;  // (libtiff prints its warnings itself)
    try {
      probe = cv::imdecode(bytes, cv::IMREAD_UNCHANGED);
    } catch (const cv::Exception&) {
    }
    (void)tiff_said.end();
    if (!probe.empty() && (probe.depth() == CV_32F || probe.depth() == CV_64F || probe.depth() == CV_16F))
      floating = "a TIFF of floating-point samples";
  }
  if (!floating.empty())
    return "cannot read as an image: it is " + floating +
           " (OpenCV would read its values into 8 bits without scaling, black or wrong): convert it to an 8- "
           "or 16-bit image first";
  CaughtStderr decoder_said;  // (libpng prints its errors itself)
  try {
    out = cv::imdecode(bytes, cv::IMREAD_COLOR);
  } catch (const cv::Exception&) {
    out.release();
  }
  const std::string said = decoder_said.end();
  if (out.empty()) {  // (a kind OpenCV does not read, named by its first bytes)
    const bool ftyp = bytes.size() >= 12 && std::memcmp(bytes.data() + 4, "ftyp", 4) == 0;
    const std::string brand = ftyp ? std::string(reinterpret_cast<const char*>(bytes.data()) + 8, 4) : "";
    std::string kind;
    if (brand == "heic" || brand == "heix" || brand == "heim" || brand == "heis" || brand == "mif1" || brand == "msf1" ||
        brand == "hevc" || brand == "hevx")
      kind = "a HEIF/HEIC image (a phone's)";
    else if (brand == "avif" || brand == "avis")
      kind = "an AVIF image";
    else if (starts("GIF87a", 6) || starts("GIF89a", 6))
      kind = "a GIF image";
    if (!kind.empty()) return "cannot read as an image: it is " + kind + ", which OpenCV does not read: convert it to JPEG or PNG";
  }
  if (!out.empty()) {
    // (CMYK, converted otherwise, is not matched exactly: taken as not turned)
    if (turn && !stored.empty() && findTurn(stored, out, *turn)) turn->stored = stored.size();
    else if (turn) turn->stored = out.size();
    return "";
  }
  return said.empty() ? "cannot read as an image" : "cannot read as an image (" + said + ")";
}
}  // namespace

std::string readImageFile(const std::string& path, cv::Mat& out) { return readImage(path, out, nullptr); }

std::string readImageFile(const std::string& path, cv::Mat& out, ImageTurn& turn) { return readImage(path, out, &turn); }

namespace {
// prepareOutputFile for a file of one kind: why it cannot be written, or ""
// with `existing` set where a file is already there whose kind the caller
// checks before writing over it.
std::string prepareKindOutputFile(const std::string& path, bool& existing) {
  existing = false;
  if (std::string problem = prepareOutputFile(path); !problem.empty()) return problem;
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) return "";
  if (!std::filesystem::is_regular_file(path, ec)) return "is not a file (a device, a pipe?): not written over";
  existing = true;
  return "";
}
}  // namespace

std::string prepareLogOutputFile(const std::string& path) {
  bool existing = false;
  if (std::string problem = prepareKindOutputFile(path, existing); !problem.empty() || !existing) return problem;
  const LcmLogCheck check = checkLcmLogStart(path);
  if (check.start == LcmLogStart::NotALog) return check.problem + ": not written over";
  if (check.start == LcmLogStart::Unreadable) return check.problem;
  return "";
}

std::string prepareVideoOutputFile(const std::string& path) {
  bool existing = false;
  if (std::string problem = prepareKindOutputFile(path, existing); !problem.empty() || !existing) return problem;
  std::ifstream f(path, std::ios::binary);
  unsigned char head[12] = {0};
  f.read(reinterpret_cast<char*>(head), sizeof head);
  const size_t n = static_cast<size_t>(f.gcount());
  if (n == 0 || (n == sizeof head && std::memcmp(head, "RIFF", 4) == 0 && std::memcmp(head + 8, "AVI ", 4) == 0))
    return "";
  return "is not an AVI video (it starts with " + hexStart(head, n) + (n > 4 ? ", ..." : "") + "): not written over";
}

std::string prepareJsonOutputFile(const std::string& path) {
  bool existing = false;
  if (std::string problem = prepareKindOutputFile(path, existing); !problem.empty() || !existing) return problem;
  std::ifstream f(path, std::ios::binary);
  char head[256] = {0};
  f.read(head, sizeof head);
  const std::string start(head, static_cast<size_t>(f.gcount()));
  const size_t first = start.find_first_not_of(" \t\r\n");
  if (first == std::string::npos || start[first] == '{' || start[first] == '[') return "";
  std::string shown = start.substr(first, 12);
  for (char& c : shown)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '.';
  return "is not a JSON file (it starts with \"" + shown + "\"): not written over";
}

std::filesystem::path resolvedPath(const std::string& path) {
  std::error_code ec;
  std::filesystem::path p = std::filesystem::weakly_canonical(std::filesystem::absolute(path, ec), ec);
  if (ec || p.empty()) p = std::filesystem::path(path).lexically_normal();
  // (a folder named with a trailing slash that does not exist yet kept it:
  // "out/" was not "out", and a file named in it seemed elsewhere)
  if (!p.has_filename() && p.has_relative_path()) p = p.parent_path();
  return p;
}

std::string writeWholeFile(const std::string& path, const std::string& bytes, int* error) {
  if (error) *error = 0;
  errno = 0;
  std::ofstream f(path, std::ios::binary);
  const bool opened = f.is_open();
  if (f) f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  if (f.is_open()) f.close();  // (a full disk shows when the buffer goes out)
  if (f) return "";
  if (error) *error = errno ? errno : EIO;
  const std::string why = errno ? std::strerror(errno) : "the write failed";
  // (a file it emptied or cut is not left as if it were whole: ld-eval's
  // table of 0 bytes; not one it never opened, a device such as /dev/full,
  // or a link, whose target it would not remove)
  std::error_code ec;
  if (opened && !std::filesystem::is_symlink(path, ec) && std::filesystem::is_regular_file(path, ec))
    std::filesystem::remove(path, ec);
  return why;
}

std::string outputsClash(const std::vector<NamedFile>& outputs, const std::vector<NamedFile>& inputs) {
  for (size_t i = 0; i < outputs.size(); ++i) {
    const auto& [option, path] = outputs[i];
    if (path.empty()) continue;
    for (const auto& [in_option, in] : inputs)
      if (!in.empty() && sameFile(path, in))
        return option + " " + path + " is the " + in_option + " file: it would be written over";
    for (size_t j = 0; j < i; ++j)
      if (!outputs[j].second.empty() && sameFile(path, outputs[j].second))
        return option + " " + path + " is also " + outputs[j].first + ": one would be written over the other";
  }
  return "";
}

bool sameFile(const std::string& a, const std::string& b) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (fs::exists(a, ec) && fs::exists(b, ec) && fs::equivalent(a, b, ec) && !ec) return true;
  return resolvedPath(a) == resolvedPath(b);
}

namespace {
// The pending file a signal would leave behind: removed by the handler
// (Ctrl-C during a long conversion left a hidden partial file of gigabytes).
char g_pending[4096] = {0};
struct sigaction g_old_int, g_old_term;

void removePendingAndExit(int sig) {
  if (g_pending[0]) ::unlink(g_pending);
  ::_exit(128 + sig);
}
}  // namespace

PendingFile::PendingFile(std::string path) : path_(std::move(path)) {
  // (through a link at the path: the file it names is the one replaced)
  std::error_code ec;
  const std::filesystem::path real = std::filesystem::weakly_canonical(path_, ec);
  if (!ec && !real.empty()) path_ = real.string();
  const std::filesystem::path p(path_);
  temp_ = (p.parent_path() / ("." + p.filename().string() + ".partial-" + std::to_string(::getpid()))).string();
  if (temp_.size() < sizeof g_pending && !g_pending[0]) {
    std::memcpy(g_pending, temp_.c_str(), temp_.size() + 1);
    struct sigaction sa {};
    sa.sa_handler = removePendingAndExit;
    sigemptyset(&sa.sa_mask);
    ::sigaction(SIGINT, &sa, &g_old_int);
    ::sigaction(SIGTERM, &sa, &g_old_term);
    owns_signals_ = true;
  }
}

PendingFile::~PendingFile() {
  if (!committed_) ::unlink(temp_.c_str());
  if (owns_signals_) {
    ::sigaction(SIGINT, &g_old_int, nullptr);
    ::sigaction(SIGTERM, &g_old_term, nullptr);
    g_pending[0] = 0;
  }
}

std::string PendingFile::commit() {
  struct stat old {};
  if (::stat(path_.c_str(), &old) == 0) ::chmod(temp_.c_str(), old.st_mode & 07777);  // (the file's mode kept)
  if (::rename(temp_.c_str(), path_.c_str()) != 0)
    return "cannot rename " + temp_ + " to " + path_ + ": " + std::strerror(errno);
  committed_ = true;
  return "";
}

bool hasExtension(const std::string& path, const std::string& extension) {
  if (path.size() < extension.size()) return false;
  return std::equal(extension.begin(), extension.end(), path.end() - static_cast<std::ptrdiff_t>(extension.size()),
                    [](char a, char b) {
                      return std::tolower(static_cast<unsigned char>(a)) == std::tolower(static_cast<unsigned char>(b));
                    });
}

}  // namespace ld
