// Joining landmark lists to images with lost and reordered messages, and the
// per-track decode schedule of ld-qr-reader.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <utility>

#include "ld/qr_tracks.hpp"
#include "ld/track_restarts.hpp"

namespace {

std::vector<uint8_t> bytes(int tag) { return std::vector<uint8_t>(10, static_cast<uint8_t>(tag)); }

void addImage(ld::FrameMatcher& m, int64_t utime, int64_t seq) {
  const auto b = bytes(static_cast<int>(seq));
  m.addImage({utime, seq}, b.data(), b.size());
}
void addList(ld::FrameMatcher& m, int64_t utime, int64_t seq) {
  const auto b = bytes(static_cast<int>(100 + seq));
  m.addList({utime, seq}, b.data(), b.size());
}

}  // namespace

TEST(FrameMatcher, PairsWhicheverArrivesFirst) {
  ld::FrameMatcher m;
  ld::FrameMatcher::Pair p;
  addImage(m, 1000, 1);
  EXPECT_FALSE(m.takeNewest(p));
  addList(m, 1000, 1);
  ASSERT_TRUE(m.takeNewest(p));
  EXPECT_EQ(p.key.seq, 1);
  EXPECT_EQ(p.image, bytes(1));
  EXPECT_EQ(p.list, bytes(101));
  addList(m, 2000, 2);  // list before its image (reordered)
  EXPECT_FALSE(m.takeNewest(p));
  addImage(m, 2000, 2);
  ASSERT_TRUE(m.takeNewest(p));
  EXPECT_EQ(p.image, bytes(2));
  EXPECT_FALSE(m.takeNewest(p));
}

TEST(FrameMatcher, LostMessagesAndNewestWins) {
  ld::FrameMatcher m(5, 5);
  ld::FrameMatcher::Pair p;
  for (int i = 0; i < 10; ++i) addImage(m, 1000 * i, i);
  addList(m, 3000, 3);  // image 3 already evicted (only 5 kept): never matched
  addList(m, 7000, 7);
  addList(m, 9000, 9);
  addList(m, 8000, 8);  // out of order
  addList(m, 12000, 12);  // its image is lost
  ASSERT_TRUE(m.takeNewest(p));
  EXPECT_EQ(p.key.seq, 9);
  EXPECT_EQ(m.skipped(), 2);  // 7 and 8 were matched but superseded
  EXPECT_FALSE(m.takeNewest(p));
  EXPECT_GE(m.unmatchedDropped(), 1);
}

TEST(FrameMatcher, SeqDisambiguatesEqualUtimes) {
  ld::FrameMatcher m;
  ld::FrameMatcher::Pair p;
  addImage(m, 1000, 1);
  addImage(m, 1000, 2);
  addList(m, 1000, 1);
  ASSERT_TRUE(m.takeNewest(p));
  EXPECT_EQ(p.image, bytes(1));
}

// A pair of a frame older than the last one taken (a list reordered on the
// way, by up to FrameMatcher::kLateUs, a second), or of that frame again, is
// dropped and counted as late: ld-qr-reader read it, took the tracks' ages
// for a tracker restart and forgot every payload (a helper held frame 5's
// list back until after frame 10). Older by more is time starting again.
TEST(FrameMatcher, LateOrRepeatedFrameIsDroppedNotRead) {
  ld::FrameMatcher m;
  ld::FrameMatcher::Pair p;
  const int64_t frame = 33'333;
  for (int i = 0; i <= 10; ++i) addImage(m, frame * i, i);
  for (int i : {40, 41}) addImage(m, frame * i, i);
  for (int i : {4, 6, 7, 40, 41}) {
    addList(m, frame * i, i);
    ASSERT_TRUE(m.takeNewest(p));
    EXPECT_EQ(p.key.seq, i);
  }
  addList(m, frame * 5, 5);  // 36 frames (1.2 s) back: more than kLateUs, time starting again
  ASSERT_TRUE(m.takeNewest(p));
  EXPECT_EQ(p.key.seq, 5);
  addList(m, frame * 6, 6);
  ASSERT_TRUE(m.takeNewest(p));
  addList(m, frame * 9, 9);
  ASSERT_TRUE(m.takeNewest(p));
  addList(m, frame * 8, 8);  // a frame late
  EXPECT_FALSE(m.takeNewest(p));
  addList(m, frame * 9, 9);  // the same frame again
  EXPECT_FALSE(m.takeNewest(p));
  EXPECT_EQ(m.late(), 2);
  EXPECT_EQ(p.key.seq, 9);  // (what was taken stays)
  addList(m, frame * 8, 8);
  addList(m, frame * 10, 10);  // late and new together: the new one taken, the late not skipped
  ASSERT_TRUE(m.takeNewest(p));
  EXPECT_EQ(p.key.seq, 10);
  EXPECT_EQ(m.late(), 3);
  EXPECT_EQ(m.skipped(), 0);
  EXPECT_EQ(m.matched(), 12);
}

// Lists (or images) that keep coming from behind, each newer than the one
// before, are time stepped back (the tracker restarted after a clock was set
// back): the third is taken (a review: half a second of lists was dropped).
TEST(FrameMatcher, TimeSteppedBackIsTakenAtTheThirdFrame) {
  ld::FrameMatcher m;
  ld::FrameMatcher::Pair p;
  const int64_t frame = 33'333;
  for (int i : {20, 21, 22}) addImage(m, frame * i, i);
  for (int i : {5, 6, 7}) addImage(m, frame * i, i);  // (0.5 s back)
  for (int i : {20, 21, 22}) {
    addList(m, frame * i, i);
    ASSERT_TRUE(m.takeNewest(p));
  }
  addList(m, frame * 5, 5);
  EXPECT_FALSE(m.takeNewest(p));
  addList(m, frame * 6, 6);
  EXPECT_FALSE(m.takeNewest(p));
  addList(m, frame * 7, 7);
  ASSERT_TRUE(m.takeNewest(p));
  EXPECT_EQ(p.key.seq, 7);
  EXPECT_EQ(m.late(), 2);
  // As the set runs: ld-tracker publishes no list for the first two frames
  // from behind, so the images count them (the lists alone dropped two more
  // of the tracker's: a review).
  ld::FrameMatcher set;
  for (int i : {20, 21, 22}) {
    addImage(set, frame * i, i);
    addList(set, frame * i, i);
    ASSERT_TRUE(set.takeNewest(p));
  }
  for (int i : {5, 6, 7}) addImage(set, frame * i, i);
  addList(set, frame * 7, 7);
  ASSERT_TRUE(set.takeNewest(p));
  EXPECT_EQ(p.key.seq, 7);
  EXPECT_EQ(set.late(), 0);
}

// A publisher whose utime stands still: frames with seqs are told apart by
// them (a later seq is taken, one up to kLateSeqs earlier is late, one
// further back is the publisher starting again); without seqs each is
// taken, as before.
TEST(FrameMatcher, StillUtimeIsOrderedBySeq) {
  ld::FrameMatcher m;
  ld::FrameMatcher::Pair p;
  for (int i = 1; i <= 3; ++i) addImage(m, 500, i);
  addList(m, 500, 2);
  ASSERT_TRUE(m.takeNewest(p));
  addList(m, 500, 3);
  ASSERT_TRUE(m.takeNewest(p));
  EXPECT_EQ(p.key.seq, 3);
  addList(m, 500, 1);
  EXPECT_FALSE(m.takeNewest(p));
  EXPECT_EQ(m.late(), 1);
  addList(m, 500, 3);  // (the same frame again)
  EXPECT_FALSE(m.takeNewest(p));
  EXPECT_EQ(m.late(), 2);
  // the publisher started again (a replay: seqs from 0 once more, the utime
  // still standing): taken, not dropped until the seqs pass the last one
  for (int i = 10; i <= 12; ++i) addImage(m, 500, i);
  addList(m, 500, 12);
  ASSERT_TRUE(m.takeNewest(p));
  for (int i = 0; i <= 2; ++i) addImage(m, 500, i);
  for (int i = 0; i <= 2; ++i) {
    addList(m, 500, i);
    ASSERT_TRUE(m.takeNewest(p)) << i;
    EXPECT_EQ(p.key.seq, i);
  }
  ld::FrameMatcher none;
  for (int i = 0; i < 3; ++i) {
    addImage(none, 500, -1);
    addList(none, 500, -1);
    EXPECT_TRUE(none.takeNewest(p));
  }
  EXPECT_EQ(none.late(), 0);
}

TEST(QrTrackBook, DecodesOnceThenRechecksRarely) {
  ld::QrScheduleParams params;
  params.retry_interval_s = 0.1;
  params.recheck_interval_s = 5.0;
  params.max_decodes_per_frame = 2;
  ld::QrTrackBook book(params);
  const int64_t s = 1000000;
  EXPECT_EQ(book.schedule({7}, 0), std::vector<int64_t>{7});
  book.record(7, 0, 0, std::nullopt);
  EXPECT_TRUE(book.schedule({7}, s / 20).empty());  // retried no sooner than 0.1 s
  EXPECT_EQ(book.schedule({7}, s / 10), std::vector<int64_t>{7});
  book.record(7, s / 10, 3, std::string("dock"));
  ASSERT_NE(book.payload(7), nullptr);
  EXPECT_EQ(book.payload(7)->payload, "dock");
  EXPECT_EQ(book.payload(7)->seq, 3);
  EXPECT_TRUE(book.schedule({7}, 2 * s).empty());  // decoded: not before 5 s
  EXPECT_EQ(book.schedule({7}, 6 * s), std::vector<int64_t>{7});
  book.record(7, 6 * s, 9, std::nullopt);  // a failed re-check keeps the payload
  EXPECT_EQ(book.payload(7)->payload, "dock");
}

// A publisher whose utime stands still: the book forgets by the frames'
// utime, so it forgot nothing, every track ever made kept and walked at each
// frame. Beyond kMaxTracks those named longest ago go; the one named all
// along keeps its payload.
TEST(QrTrackBook, HoldsAtMostItsBoundWhenTimeStandsStill) {
  ld::QrTrackBook book;
  book.schedule({1}, 5000);
  book.record(1, 5000, 0, std::string("dock"));
  const int64_t n = static_cast<int64_t>(ld::QrTrackBook::kMaxTracks) * 2;
  for (int64_t k = 0; k < n; ++k) {
    book.schedule({1, 100 + k}, 5000);  // the dock, and a new track in each frame
    ASSERT_LE(book.size(), ld::QrTrackBook::kMaxTracks * 11 / 10 + 1) << k;
  }
  EXPECT_GE(book.size(), ld::QrTrackBook::kMaxTracks);
  ASSERT_NE(book.payload(1), nullptr);
  EXPECT_EQ(book.payload(1)->payload, "dock");
}

// A read track made due at once (readAgain: its look saw another code) is
// re-read before the 5 s, its payload kept, but after every undecoded track
// (its priority once came out below theirs and took the frame's decode).
TEST(QrTrackBook, ReadAgainComesAfterTheUndecodedTracks) {
  ld::QrScheduleParams params;
  params.max_decodes_per_frame = 1;
  ld::QrTrackBook book(params);
  const int64_t s = 1000000;
  EXPECT_EQ(book.schedule({7, 8}, 10 * s), std::vector<int64_t>{7});
  book.record(7, 10 * s, 0, std::string("dock"));
  EXPECT_EQ(book.schedule({7, 8}, 10 * s + 1), std::vector<int64_t>{8});
  book.record(8, 10 * s + 1, 1, std::nullopt);
  book.readAgain(7);
  book.readAgain(99);  // (unknown: nothing)
  EXPECT_EQ(book.size(), 2u);
  EXPECT_EQ(book.payload(7)->payload, "dock");
  // 8 due again (0.1 s on) comes first; 7 once 8 is not due
  EXPECT_EQ(book.schedule({7, 8}, 10 * s + s / 5), std::vector<int64_t>{8});
  book.record(8, 10 * s + s / 5, 2, std::nullopt);
  EXPECT_EQ(book.schedule({7, 8}, 10 * s + s / 5 + 1), std::vector<int64_t>{7});
}

// Intervals too long to count in microseconds are never, not (as the cast
// overflowed) every frame: `--recheck-interval 1e300` re-read a track on
// each.
TEST(QrTrackBook, HugeIntervalsAreNever) {
  ld::QrScheduleParams params;
  params.retry_interval_s = 1e300;
  params.recheck_interval_s = 1e300;
  params.forget_after_s = 1e300;
  ld::QrTrackBook book(params);
  const int64_t s = 1000000;
  EXPECT_EQ(book.schedule({1, 2}, 0), (std::vector<int64_t>{1, 2}));  // (the first try of each)
  book.record(1, 0, 0, std::string("dock"));
  book.record(2, 0, 0, std::nullopt);
  for (int64_t t : {s, 3600 * s, int64_t{1} << 61}) EXPECT_TRUE(book.schedule({1, 2}, t).empty()) << t;
  EXPECT_NE(book.payload(1), nullptr);
}

// A read track whose landmark jumps (by more than its size per tracker frame)
// is another landmark: the tracker moved its id over. Its payload is
// forgotten and the track is the first read again; moving as a landmark
// moves (less than its size a frame, over frames the reader skipped too),
// an older frame matched late, and tracks never scheduled keep everything.
// (An audit: a decoded track moved onto a patch without a QR kept publishing
// its old payload for the 9 s it was watched.)
TEST(QrTrackBook, ReadTrackThatJumpsIsReadAgain) {
  ld::QrTrackBook book;
  EXPECT_EQ(book.follow(9, 0, true, 100, 100, 40), std::nullopt);  // (not known: nothing)
  book.schedule({1, 2}, 0);
  book.record(1, 0, 0, std::string("room-101"));
  book.record(2, 0, 0, std::string("room-102"));
  EXPECT_EQ(book.follow(1, 10, true, 100, 100, 40), std::nullopt);  // placed
  EXPECT_EQ(book.follow(2, 10, true, 400, 100, 40), std::nullopt);
  EXPECT_FALSE(book.strayed(1));
  EXPECT_EQ(book.follow(1, 11, true, 130, 100, 40), std::nullopt);  // 30 px in a frame: moving
  EXPECT_TRUE(book.strayed(1));  // (30 px from where it stood: more than half a jump, looked at)
  EXPECT_EQ(book.follow(1, 14, true, 230, 100, 40), std::nullopt);  // 100 px over 3 frames
  EXPECT_FALSE(book.strayed(1));  // (10 px from where its motion led)
  EXPECT_EQ(book.follow(1, 13, true, 600, 100, 40), std::nullopt);  // an older frame: no news
  ASSERT_NE(book.payload(1), nullptr);
  EXPECT_EQ(book.payload(1)->payload, "room-101");
  EXPECT_EQ(book.follow(2, 11, true, 405, 100, 40), std::nullopt);
  // track 1 is now 300 px away in one frame: another landmark
  EXPECT_EQ(book.follow(1, 15, true, 530, 300, 40), std::optional<std::string>("room-101"));
  EXPECT_EQ(book.payload(1), nullptr);
  EXPECT_NE(book.payload(2), nullptr);
  const auto todo = book.schedule({2, 1}, 1000);  // 1 at once (2 is read: not due)
  EXPECT_EQ(todo, std::vector<int64_t>{1});
  book.record(1, 1000, 15, std::string("room-103"));
  EXPECT_EQ(book.follow(1, 16, true, 531, 300, 40), std::nullopt);
  EXPECT_EQ(book.payload(1)->payload, "room-103");
  // a coasting landmark's place is the tracker's guess: not looked at
  EXPECT_EQ(book.follow(1, 17, false, 900, 900, 40), std::nullopt);
  EXPECT_EQ(book.payload(1)->payload, "room-103");
  // bad input is ignored
  EXPECT_EQ(book.follow(1, 17, true, std::nan(""), 0, 40), std::nullopt);
  EXPECT_EQ(book.follow(1, 17, true, 0, 0, 0), std::nullopt);
  EXPECT_EQ(book.payload(1)->payload, "room-103");
}

// A read track seen coasting and then detected again more than 1.5 sizes
// from its path (from its last place to where its motion leads) is another
// landmark, however long it coasted: the tracker's gate let another in (an
// audit: a landmark left the image as another came in on the other side,
// the tracker gave the newcomer its id, and with the allowance of a size per
// frame over the 21 frames coasted the first one's payload stayed on it for
// 5 s). Frames the reader skipped, the track detected in them, still allow
// a size each; anywhere near its path (the robot stopped on the way, or the
// velocity was a little off) it keeps its payload.
TEST(QrTrackBook, ReadTrackFoundAgainAfterCoastingIsCheckedAgainstItsPath) {
  const auto book = [](bool seen_coasting) {
    auto b = std::make_unique<ld::QrTrackBook>();
    b->schedule({1}, 0);
    b->record(1, 0, 0, std::string("E1"));
    // at 260, moving 10 px a frame to the left; its motion leads to 40 at frame 26
    for (int k = 0; k < 5; ++k) EXPECT_EQ(b->follow(1, k, true, 300 - 10 * k, 200, 100), std::nullopt);
    for (int k = 5; k < 26 && seen_coasting; ++k)
      EXPECT_EQ(b->follow(1, k, false, 300 - 10 * k, 200, 100), std::nullopt);
    return b;
  };
  {  // 1.6 sizes beside its path
    auto b = book(true);
    EXPECT_EQ(b->follow(1, 26, true, 150, 360, 100), std::optional<std::string>("E1"));
  }
  {  // 260 px right of its last place: across the image from its path
    auto b = book(true);
    EXPECT_EQ(b->follow(1, 26, true, 520, 200, 100), std::optional<std::string>("E1"));
    EXPECT_EQ(b->payload(1), nullptr);
  }
  {  // the same, not seen coasting (the lists skipped): 26 sizes allowed
    auto b = book(false);
    EXPECT_EQ(b->follow(1, 26, true, 520, 200, 100), std::nullopt);
    ASSERT_NE(b->payload(1), nullptr);
  }
  // on its path (stopped at 180, or where it led), or 1.4 sizes beside it
  for (const auto& [x, y] : {std::pair{180.0, 200.0}, {40.0, 200.0}, {150.0, 340.0}, {-100.0, 200.0}}) {
    auto b = book(true);
    EXPECT_EQ(b->follow(1, 26, true, x, y, 100), std::nullopt) << x << ", " << y;
    ASSERT_NE(b->payload(1), nullptr) << x << ", " << y;
    EXPECT_EQ(b->payload(1)->payload, "E1");
  }
}

// A step before the track's motion is known (just placed) is judged from
// its last place, and so is a track found again after coasting before its
// motion was known (reviews of rules tried and taken out: one that did not
// judge such steps let an id given to another landmark at the track's
// second step keep the payload, and one found 300 px away after 20 frames
// coasted too).
TEST(QrTrackBook, StepBeforeTheMotionIsKnownIsStillJudged) {
  // read "A" at list 0, placed at list 1 (size `size`, at x), coasting until list `coast_to`
  const auto book = [](double x, double size, int coast_to) {
    auto b = std::make_unique<ld::QrTrackBook>();
    b->schedule({1}, 0);
    b->record(1, 0, 0, std::string("A"));
    EXPECT_EQ(b->follow(1, 1, true, x, 200, size), std::nullopt);
    for (int k = 2; k < coast_to; ++k) EXPECT_EQ(b->follow(1, k, false, x, 200, size), std::nullopt);
    return b;
  };
  {  // the id given to another landmark at list 2
    auto b = book(105, 30, 2);
    EXPECT_EQ(b->follow(1, 2, true, 300, 200, 30), std::optional<std::string>("A"));
  }
  {  // coasting 20 lists, found at a neighbour 300 px away
    auto b = book(200, 60, 22);
    EXPECT_EQ(b->follow(1, 22, true, 500, 200, 60), std::optional<std::string>("A"));
  }
  {  // ... found where it was: kept
    auto b = book(200, 60, 22);
    EXPECT_EQ(b->follow(1, 22, true, 250, 230, 60), std::nullopt);
    ASSERT_NE(b->payload(1), nullptr);
  }
}

// The first decode of a frame always runs; later ones while the budget lasts.
TEST(DecodeBudget, FirstAlwaysThenWhileTheBudgetLasts) {
  using ms = std::chrono::milliseconds;
  const ld::DecodeBudget::Clock::time_point t0{};
  ld::DecodeBudget b(30);
  EXPECT_TRUE(b.allows(t0 + ms(1000)));  // the first, whenever
  EXPECT_TRUE(b.allows(t0 + ms(1020)));
  EXPECT_TRUE(b.allows(t0 + ms(1029)));
  EXPECT_FALSE(b.allows(t0 + ms(1030)));
  EXPECT_FALSE(b.allows(t0 + ms(1100)));
  ld::DecodeBudget tight(1);
  EXPECT_TRUE(tight.allows(t0));
  EXPECT_FALSE(tight.allows(t0 + ms(80)));  // (one slow decode spends it)
}

// A small far landmark the tracker follows through a fast turn, faster than
// its size a frame: where its motion so far leads is where it is, and its
// payload stays (a review: compared with its last place alone, "room-101"
// was forgotten at the second frame of the turn, and a far landmark in a
// turn cannot be read again).
TEST(QrTrackBook, ReadTrackMovingFasterThanItsSizeKeepsItsPayload) {
  ld::QrTrackBook book;
  book.schedule({1}, 0);
  book.record(1, 0, 0, std::string("room-101"));
  double x = 100, v = 0;
  for (int k = 0; k < 12; ++k) {
    EXPECT_EQ(book.follow(1, k, true, x, 200, 30), std::nullopt) << "frame " << k << ", " << v << " px a frame";
    v = std::min(v + 8, 45.0);  // up to 1.5 sizes a frame
    x += v;
  }
  ASSERT_NE(book.payload(1), nullptr);
  EXPECT_EQ(book.payload(1)->payload, "room-101");
}

TEST(QrTrackBook, BoundedWorkPerFrameUndecodedFirst) {
  ld::QrScheduleParams params;
  params.max_decodes_per_frame = 2;
  ld::QrTrackBook book(params);
  book.schedule({1}, 0);
  book.record(1, 0, 0, std::string("a"));
  const int64_t t = 10000000;  // 10 s later: track 1 is due for a re-check
  const auto todo = book.schedule({1, 2, 3, 4}, t);
  ASSERT_EQ(todo.size(), 2u);
  EXPECT_EQ(todo[0], 2);
  EXPECT_EQ(todo[1], 3);
  for (int64_t id : todo) book.record(id, t, 1, std::nullopt);
  const auto next = book.schedule({1, 2, 3, 4}, t + 200000);
  ASSERT_EQ(next.size(), 2u);
  EXPECT_EQ(next[0], 4);  // never tried comes before tried
}

TEST(QrTrackBook, ForgetsTracksUnseenForLong) {
  ld::QrTrackBook book;
  book.schedule({5}, 0);
  book.record(5, 0, 0, std::string("x"));
  book.schedule({6}, 20000000);
  EXPECT_EQ(book.payload(5), nullptr);
  EXPECT_EQ(book.size(), 1u);
}

// A tracker that restarted numbers its tracks from 1 again: an id seen
// younger than it was is another landmark, and nothing read under the old
// tracker's ids is kept. Ages a few frames back (reordered messages) and
// ages going on are the same track.
TEST(QrTrackBook, ForgetsEverythingWhenTrackIdsStartAgain) {
  ld::QrTrackBook book;
  EXPECT_FALSE(book.noteAges({{1, 40}, {2, 38}}));
  book.schedule({1, 2}, 0);
  book.record(1, 0, 40, std::string("room-101"));
  book.record(2, 0, 40, std::string("room-102"));
  EXPECT_FALSE(book.noteAges({{1, 41}, {2, 39}}));
  EXPECT_FALSE(book.noteAges({{1, 39}, {2, 37}}));  // (an older frame, matched late)
  ASSERT_NE(book.payload(1), nullptr);
  EXPECT_EQ(book.payload(1)->payload, "room-101");
  // the tracker restarted: track 1 is now a new landmark, 3 frames old
  EXPECT_TRUE(book.noteAges({{1, 3}}));
  EXPECT_EQ(book.payload(1), nullptr);
  EXPECT_EQ(book.payload(2), nullptr);
  EXPECT_EQ(book.size(), 0u);  // (the new tracks come in as they are scheduled)
  // the new track 1 is scheduled at once, read, and kept as it grows
  EXPECT_EQ(book.schedule({1}, 1000), std::vector<int64_t>{1});
  book.record(1, 1000, 5, std::string("room-103"));
  EXPECT_FALSE(book.noteAges({{1, 4}, {2, 0}}));
  ASSERT_NE(book.payload(1), nullptr);
  EXPECT_EQ(book.payload(1)->payload, "room-103");
}

// The watch behind noteAges and ld-run's report: between two lists naming a
// track, its age grows by at least the lists in between; less (by more than
// 3 frames) is another track under the same id.
TEST(TrackRestartWatch, TellsARestartFromTheTracksAges) {
  ld::TrackRestartWatch w;
  for (int32_t age = 0; age < 10; ++age) EXPECT_FALSE(w.note({{1, age}, {2, age}}));
  EXPECT_FALSE(w.note({{1, 6}, {2, 6}}));    // a list 3 frames old, read late (the slack)
  EXPECT_FALSE(w.note({{1, 10}, {2, 10}}));  // and on
  EXPECT_FALSE(w.note({{1, 30}}));           // lists lost: the age grew more
  EXPECT_EQ(w.restarts(), 0);
  EXPECT_TRUE(w.note({{1, 0}}));  // 0 frames old: a new tracker's track 1
  EXPECT_FALSE(w.note({{1, 1}}));
  EXPECT_EQ(w.restarts(), 1);
  EXPECT_EQ(w.size(), 1u);  // only the new run's tracks are known
  EXPECT_FALSE(w.note({{1, 2}, {2, 0}}));
  // 4 frames late is beyond the slack: another track
  ld::TrackRestartWatch late;
  for (int32_t age = 0; age < 10; ++age) EXPECT_FALSE(late.note({{1, age}}));
  EXPECT_TRUE(late.note({{1, 5}}));
}

// A reader that forgets tracks not named for N lists keeps its memory
// bounded (tracks seen only coasting included) and still tells a restart
// from the tracks it knows.
TEST(TrackRestartWatch, ForgetsTracksNotNamedForLong) {
  ld::TrackRestartWatch w(300);
  for (int32_t i = 0; i < 1000; ++i) EXPECT_FALSE(w.note({{i + 1, 0}, {10000, i}}));  // a new id each list
  EXPECT_LE(w.size(), 300u + 256u + 1u);
  EXPECT_TRUE(w.note({{10000, 2}}));  // the long track, young again
}

// A track the old tracker had for two frames, gone long before the restart:
// its age alone (2, now 0) is within the slack, but 100 lists later a track
// that went on would be over 100 frames old.
TEST(TrackRestartWatch, TellsARestartFromAnIdGoneLongAgo) {
  ld::TrackRestartWatch w;
  EXPECT_FALSE(w.note({{5, 1}}));
  EXPECT_FALSE(w.note({{5, 2}}));
  for (int32_t i = 0; i < 100; ++i) EXPECT_FALSE(w.note({{6, 40 + i}}));
  EXPECT_TRUE(w.note({{5, 0}}));
  // a track not listed for a while (coasting unreported) that went on is not a restart
  ld::TrackRestartWatch v;
  EXPECT_FALSE(v.note({{1, 3}}));
  for (int32_t i = 0; i < 50; ++i) EXPECT_FALSE(v.note({}));
  EXPECT_FALSE(v.note({{1, 53}}));
}
