#include <fstream>
#include <stdexcept>

#include <gtest/gtest.h>

#include "core/test_session_support.hpp"
#include "nirslam/common/error.hpp"
#include "nirslam/session/session_recorder.hpp"
#include "nirslam/session/session_source.hpp"

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;

fs::path recorded_session(const std::string& name, int frames) {
  const fs::path session = fresh_session_dir(name) / "s";
  RecorderOptions options;
  options.min_free_bytes_to_start = 0;
  options.min_free_bytes_while_recording = 0;
  SessionRecorder recorder(session, {"test", "replayed", 20.0, nullptr}, options);
  for (int i = 0; i < frames; ++i) recorder.record(synthetic_frame(i));
  recorder.stop("end of source");
  return session;
}

TEST(SessionSource, ReplaysWithTrueTimestampsAndIsASessionSource) {
  const fs::path session = recorded_session("replay", 10);
  SessionSource source(session);
  EXPECT_EQ(source.info().kind, "session");
  EXPECT_EQ(source.info().frame_count, 10u);
  EXPECT_DOUBLE_EQ(source.info().nominal_fps, 20.0);
  EXPECT_FALSE(source.info().live);
  EXPECT_EQ(source.camera(), nullptr);
  for (int i = 0; i < 10; ++i) {
    const std::optional<Frame> frame = source.next();
    ASSERT_TRUE(frame);
    EXPECT_DOUBLE_EQ(frame->timestamp_s, synthetic_frame(i).timestamp_s) << "recorded, not re-timed";
    EXPECT_NE(frame->name.find("frames/0000"), std::string::npos) << frame->name;
  }
  EXPECT_FALSE(source.next());
  source.rewind();
  EXPECT_EQ(source.next()->index, 0);
}

TEST(SessionSource, SeeksToAnyFrameAndRefusesPastTheEnd) {
  const fs::path session = recorded_session("seek", 10);
  SessionSource source(session);
  source.seek(7);
  EXPECT_EQ(source.position(), 7u);
  std::optional<Frame> frame = source.next();
  ASSERT_TRUE(frame);
  EXPECT_EQ(frame->index, 7);
  EXPECT_TRUE(same_pixels(frame->image, synthetic_frame(7).image));
  EXPECT_DOUBLE_EQ(*frame->exposure_ms, *synthetic_frame(7).exposure_ms);
  source.seek(2);
  EXPECT_TRUE(same_pixels(source.next()->image, synthetic_frame(2).image));
  EXPECT_THROW(source.seek(10), std::out_of_range);
  EXPECT_EQ(source.position(), 3u) << "a refused seek keeps the place";
}

TEST(SessionSource, OpensThroughTheSourceArgumentHelpers) {
  const fs::path session = recorded_session("open", 3);
  EXPECT_TRUE(is_session_folder(session));
  EXPECT_FALSE(is_session_folder(session / "frames"));
  const std::unique_ptr<Source> source = open_session_source(session);
  EXPECT_EQ(source->info().kind, "session");
  EXPECT_EQ(source->info().frame_count, 3u);
}

TEST(SessionSource, AMissingFrameFileIsNamed) {
  const fs::path session = recorded_session("missing_frame", 3);
  fs::remove(session / "frames/000001.png");
  SessionSource source(session);
  source.next();
  try {
    source.next();
    FAIL() << "read a frame whose file is gone";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("000001.png"), std::string::npos) << e.what();
  }
}

TEST(SessionSource, AMalformedJournalLineIsNamedWithFileLineAndField) {
  const fs::path session = recorded_session("bad_journal", 3);
  std::ofstream(session / session_files::kJournal, std::ios::app)
      << "3,3,abc,,,,,8,frames/000003.png,10,,,,,,,,,,,,,,\n";
  try {
    SessionSource source(session);
    FAIL() << "accepted a malformed journal";
  } catch (const InputError& e) {
    EXPECT_EQ(e.line(), 5);
    EXPECT_NE(std::string(e.what()).find("journal.csv"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("timestamp_s"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace nirslam::testing
