// A QR symbol's codewords corrected with erasures, for the QR reader's
// module-by-module path (qr_reader.cpp). Not a public interface; tests
// include it by its path.
//
// zbar corrects a code's errors from hard decisions: a Reed-Solomon block
// with r check codewords corrects r / 2 wrong codewords, and where a module
// is about a pixel, more of them are wrong than that. But the reader knows
// how sure it is of each module (how far the equaliser's estimate lies from
// its threshold), and a block corrects e errors and f erasures (codewords
// known to be doubtful, their values ignored) as long as 2e + f <= r. So the
// corrector reads the format (error correction level and mask) from both of
// its copies, takes each block's codewords out of the grid (ISO/IEC 18004,
// section 7.7.3), and decodes each block with more and more of its least
// sure codewords erased (generalised minimum distance decoding), stopping
// short of the block's whole capacity so that a wrong correction stays
// unlikely; the corrected codewords are put back in the grid, which zbar
// then reads (its own error correction finds nothing to mend, and it parses
// the payload as it parses any code).
#pragma once

#include <cstdint>
#include <vector>

namespace ld::detail {

/// Error correction levels in the format's order of strength.
enum class QrLevel { L = 0, M = 1, Q = 2, H = 3 };

/// The Reed-Solomon blocks of a version (1..15) at a level: `ec` check
/// codewords per block, `blocks1` blocks of `data1` data codewords, then
/// `blocks2` of `data1 + 1` (ISO/IEC 18004 table 9).
struct QrBlocks {
  int ec, blocks1, data1, blocks2;
  int total() const { return (blocks1 * data1 + blocks2 * (data1 + 1)) + (blocks1 + blocks2) * ec; }
};
QrBlocks qrBlocks(int version, QrLevel level);

/// The 15 bits of the format information for a level and mask (0..7), as
/// the symbol carries them (BCH-coded and XORed with 0x5412).
int qrFormatBits(QrLevel level, int mask);

/// Whether module (r, c) of an n-module symbol carries data (not a finder, its
/// separator, a timing or alignment pattern, the format or version
/// information, or the dark module).
std::vector<uint8_t> qrDataModules(int n);

/// Corrects `block` (data codewords then `ec` check codewords, first
/// codeword the highest power, the QR's generator with roots a^0..a^(ec-1)
/// over GF(256), x^8 + x^4 + x^3 + x^2 + 1) in place, with the codewords at
/// `erasures` (indices into the block, distinct) known to be doubtful.
/// Returns the number of errors found outside the erasures, or -1 when the
/// block cannot be corrected (then `block` is as it was).
int rsCorrect(std::vector<uint8_t>& block, int ec, const std::vector<int>& erasures);

/// The corrector: owns its buffers, so nothing is allocated once warm for
/// symbols of the sizes it has seen.
class QrCorrector {
 public:
  /// `darkness`: n x n values, row-major, 1 for a module surely dark, 0 for
  /// one surely light, 0.5 undecided (values outside [0, 1] are as sure as
  /// the nearer end). On success `modules` (n x n, 1 dark) is the corrected
  /// symbol, its function patterns and format drawn ideal, and true is
  /// returned; false when the format or a block cannot be corrected.
  bool correct(int n, const float* darkness, std::vector<uint8_t>& modules);

  /// What the last successful correct() did, summed over the blocks.
  int lastErasures() const { return last_erasures_; }
  int lastErrors() const { return last_errors_; }

 private:
  bool correctAs(int n, int version, QrLevel level, int mask, const float* darkness, std::vector<uint8_t>& modules);
  std::vector<uint8_t> data_, raw_, block_;
  std::vector<int> order_, erasures_, by_doubt_;
  std::vector<float> sure_, block_sure_;
  std::vector<std::vector<uint8_t>> blocks_;
  int data_n_ = 0;
  int last_erasures_ = 0, last_errors_ = 0;
};

}  // namespace ld::detail
