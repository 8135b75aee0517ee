// Checks the tools make on their files before they start, so that a wrong
// path gets one clear line at once instead of a child process failing (and
// being restarted) or a library printing its own warnings.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

namespace ld {

/// LCM's log format (lcm-logger, lcm_eventlog): each event starts with this
/// magic, big-endian, then the event number and the timestamp (8 bytes
/// each), the channel's and the data's lengths (4 bytes each).
constexpr uint32_t kLcmLogMagic = 0xEDA1DA01;
constexpr size_t kLcmLogHeaderBytes = 28;

/// What the start of a file says about it as an LCM log.
enum class LcmLogStart {
  Events,       ///< a whole first event header with the magic
  Empty,        ///< no bytes at all (a logger that recorded nothing)
  Unreadable,   ///< cannot be opened or read
  NotALog,      ///< does not start with the magic
  CutInHeader,  ///< starts with the magic but ends inside the first header
};

struct LcmLogCheck {
  LcmLogStart start = LcmLogStart::Unreadable;
  /// Empty for Events; otherwise why, to follow the path in a message:
  /// "cannot be read: No such file or directory", "is empty",
  /// "is not an LCM log (it starts with 89 50 4e 47, not LCM's event magic ed a1 da 01)",
  /// "ends inside its first event header (10 of 28 bytes)".
  std::string problem;
  std::string error;  ///< Unreadable: the system's reason ("No such file or directory")
};

/// Reads the first event header of `path` (nothing more).
LcmLogCheck checkLcmLogStart(const std::string& path);

/// Whether `path` ends in `extension` (".png", ".avi"), in any case: the
/// tools that write a format by its name (a plot, a video) say so when it
/// does not.
bool hasExtension(const std::string& path, const std::string& extension);

/// Makes sure files can be created in `folder`: creates it (and its parents)
/// when missing, then creates and removes a temporary file in it. Empty when
/// they can; otherwise why, as prepareOutputFile says it.
std::string prepareOutputFolder(const std::string& folder);

/// Makes sure a file can be created at `path`: prepareOutputFolder on its
/// folder (the working folder for a bare name), and an existing file must
/// be writable. Empty when it can; otherwise why,
/// to follow the path in a message: "is a folder", "cannot create folder
/// /proc/x: No such file or directory", "cannot write in folder /x:
/// Read-only file system".
std::string prepareOutputFile(const std::string& path);

/// What a library prints on stderr by itself meanwhile (libpng's "libpng
/// error: bad adaptive filter value" during cv::imdecode, OpenCV's AVI
/// reader's lines), caught so that the caller says it in its own one line,
/// or not at all: from construction to end() (or destruction), standard
/// error goes to an anonymous memory file, so whatever the process prints
/// from another thread then is caught too (use it in one thread). Where it
/// cannot be set up, nothing is caught.
class CaughtStderr {
 public:
  CaughtStderr();
  ~CaughtStderr();
  CaughtStderr(const CaughtStderr&) = delete;
  CaughtStderr& operator=(const CaughtStderr&) = delete;
  /// Standard error back as it was; what was printed meanwhile, its lines
  /// joined by "; ", without lines that say "warning" ("libpng warning:
  /// iCCP: known incorrect sRGB profile"), cut at 1000 characters; "" when
  /// nothing.
  std::string end();

 private:
  void restore();
  int file_ = -1, saved_ = -1;
};

/// The video frames an AVI file holds whole: its '##dc' and '##db' chunks
/// whose data lies within the file, in the 'movi' lists of its first RIFF
/// section and of any 'AVIX' sections after it (FFmpeg's writer goes on in
/// those past 1 GiB; OpenCV's own reader counts the first section alone). A
/// video cut short (a full disk) counts the frames before the cut. -1 when
/// the file is not an AVI or cannot be read.
int64_t aviVideoFrames(const std::string& path);

/// Reads an image file (any format OpenCV reads) into 8-bit BGR, reading the
/// file once. Empty when it did; otherwise why, to follow the path in a
/// message: "no such file", "is a loop of symbolic links", "is not a file
/// (a pipe, a device?)" (a pipe would block, or be read up to its end),
/// "is 600 MiB: more than an image file has (512 MiB at most)", "cannot
/// read as an image: it is a JPEG cut short (no end-of-image marker)"
/// (OpenCV reads such a file as an image with grey rows), "cannot read as
/// an image: it is a JPEG that is damaged (libjpeg: ...)", "cannot read as
/// an image (libpng error: PNG input buffer is incomplete)" (what the image
/// library printed on stderr itself during the decode, caught: standard
/// error goes elsewhere meanwhile, so call it from one thread), "cannot
/// read as an image: it is a PFM image (...)" (floating-point images: PFM,
/// OpenEXR, a TIFF of floats, which OpenCV reads into 8 bits unscaled),
/// "cannot read as an image".
std::string readImageFile(const std::string& path, cv::Mat& out);

/// Whether a file's name has the extension of an image kind the readers
/// take (any case): .png, .jpg, .jpeg, .jpe, .jfif, .bmp, .ppm, .pgm, .pbm,
/// .pnm, .tif, .tiff, .webp, .jp2, .hdr, .pic, .sr, .ras, and the
/// floating-point .exr and .pfm (named and refused when read).
bool isImageFileName(const std::filesystem::path& path);
/// Those extensions, for people: ".png, .jpg, ...".
std::string imageFileExtensions();

/// A folder's image files (isImageFileName; links whose file is gone and
/// pipes with an image's name too: reading them says so), in name order.
/// `unread` gets the names (not paths) of its files of image kinds OpenCV
/// does not read: HEIC/HEIF (a phone's), AVIF, GIF and camera raw
/// (.dng, .cr2, .cr3, .nef, .arw, .orf, .rw2, .raf), passed over otherwise
/// without a word. Returns "" or why the folder could not be listed
/// ("Permission denied").
std::string listImageFolder(const std::string& dir, std::vector<std::string>& files, std::vector<std::string>& unread);
/// For `unread`'s names: "2 files of image kinds OpenCV does not read left
/// out (IMG_0001.HEIC, a.gif): convert them to JPEG or PNG".
std::string describeUnreadImages(const std::vector<std::string>& unread);

/// How an image file's stored pixels were turned into the image read: a
/// JPEG's Exif orientation (a phone stores a portrait photo as its sensor
/// took it, landscape, and says how to turn it upright; OpenCV turns it):
/// mirrored left to right first where `mirrored`, then turned
/// `quarter_turns_cw` quarter turns clockwise. `stored` is the stored
/// image's size.
struct ImageTurn {
  int quarter_turns_cw = 0;
  bool mirrored = false;
  cv::Size stored;
  bool any() const { return quarter_turns_cw != 0 || mirrored; }
};
/// readImageFile, and how the image was turned from the file's pixels.
std::string readImageFile(const std::string& path, cv::Mat& out, ImageTurn& turn);

/// prepareOutputFile for an LCM log about to be written: besides, a file
/// already at `path` must be an LCM log (or empty), so that a log is never
/// written over an image, a video or anything else a user meant as input.
/// Empty when it can; otherwise why ("is not an LCM log (it starts with
/// 89 50 4e 47, ...): not written over").
std::string prepareLogOutputFile(const std::string& path);

/// prepareOutputFile for an AVI video about to be written: besides, a file
/// already at `path` must be an AVI (an earlier video) or empty, so that a
/// video is never written over a log, an image or notes. Empty when it can;
/// otherwise why ("is not an AVI video (it starts with ed a1 da 01, ...):
/// not written over").
std::string prepareVideoOutputFile(const std::string& path);

/// prepareOutputFile for a JSON file about to be written (a summary, a state
/// file): besides, a file already at `path` must be JSON (its first
/// character other than white space '{' or '['), or empty. Empty when it
/// can; otherwise why ("is not a JSON file (it starts with "# robot"): not
/// written over").
std::string prepareJsonOutputFile(const std::string& path);

/// A path made absolute and resolved (links, "..", "."), as far as it exists;
/// one that cannot be resolved, only normalized. For comparing paths.
std::filesystem::path resolvedPath(const std::string& path);

/// Whether two paths name the same file: the same resolvedPath, or, when
/// both exist, the same file (a hard link). For the tools' refusals of an
/// output that is one of their inputs.
bool sameFile(const std::string& a, const std::string& b);

/// Writes `bytes` to `path` (made or emptied first) and closes it; "" when
/// all of it was written, else why not ("No space left on device"), the
/// file it emptied or cut removed (a device it writes to is left). `error`,
/// where given, gets the errno of a failure (EIO where none was set), 0
/// otherwise.
std::string writeWholeFile(const std::string& path, const std::string& bytes, int* error = nullptr);

/// A file a program reads or writes, with the option that names it:
/// {"--params", "my.yaml"}. An empty path is no file.
using NamedFile = std::pair<std::string, std::string>;
/// What is wrong when an output is one of the inputs or another output
/// (sameFile), for a tool's one-line refusal before it writes anything:
/// "--markdown my.yaml is the --params file: it would be written over",
/// "--png a.png is also --markdown: one would be written over the other";
/// "" when nothing is.
std::string outputsClash(const std::vector<NamedFile>& outputs, const std::vector<NamedFile>& inputs);

/// A file written under a temporary name beside its path and renamed to it
/// by commit(): a run that fails half-way leaves what was at the path as it
/// was (an earlier good log, say), and no half-written file behind, a run
/// stopped by SIGINT or SIGTERM included (while it is pending, they remove
/// it and end the process, status 128 + the signal). A path that is a link
/// replaces the file the link names; the file's mode is kept.
class PendingFile {
 public:
  explicit PendingFile(std::string path);
  ~PendingFile();
  PendingFile(const PendingFile&) = delete;
  PendingFile& operator=(const PendingFile&) = delete;
  /// Where to write until commit().
  const std::string& tempPath() const { return temp_; }
  /// Renames the written file to the path; empty when done, otherwise why.
  std::string commit();

 private:
  std::string path_, temp_;
  bool committed_ = false, owns_signals_ = false;
};

}  // namespace ld
