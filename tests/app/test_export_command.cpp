#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include "app/cli_runner.hpp"
#include "nirslam/image/image_codec.hpp"
#include "nirslam/sources/tum_monovo_reader.hpp"

namespace nirslam::testing {
namespace {

namespace fs = std::filesystem;

// One recorded simulated tunnel, with the calibrated pipeline (trajectory, calibration, ground
// truth), shared by the tests of this file when they run in one process. ctest runs each test in
// its own process, in parallel: each records into its own folder.
const fs::path& recorded_tunnel() {
  static const fs::path session = [] {
    const std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    const fs::path s = fresh_dir("export_tunnel_" + test) / "session";
    const CommandResult r =
        run_command(nirslam("record sim:tunnel --frames 60 --mode calibrated --out '" + s.string() + "'"));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return s;
  }();
  return session;
}

TEST(ExportCommand, WritesATumDatasetTheProjectReaderReadsBack) {
  const fs::path out = fresh_dir("export_dataset") / "tunnel";
  const CommandResult r = run_command(nirslam("export '" + recorded_tunnel().string() + "' --out '" + out.string() + "' --archive"));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("Exported 60 frames"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("ATE RMSE"), std::string::npos) << "ground truth and trajectory give the accuracy\n" << r.output;
  for (const char* file : {"times.txt", "camera.txt", "pcalib.txt", "vignette.png", "trajectory.txt", "keyframes.txt",
                           "points.ply", "groundtruth.txt", "frames.csv", "metrics.csv", "report.html",
                           "report/entropy.png", "report/photometric.png", "report/trajectory.png",
                           "report/error_heatmap.png"})
    EXPECT_TRUE(fs::exists(out / file)) << file << "\n" << r.output;
  EXPECT_TRUE(fs::exists(out.string() + ".zip"));

  TumMonoVoReader reader(out);
  EXPECT_EQ(reader.info().frame_count, 60u);
  ASSERT_TRUE(reader.calibration());
  int frames = 0;
  while (const auto frame = reader.next()) {
    EXPECT_TRUE(frame->exposure_ms.has_value()) << "times.txt carries the exposures";
    ++frames;
  }
  EXPECT_EQ(frames, 60);
}

TEST(ExportCommand, AMissingSessionIsNamed) {
  const CommandResult r = run_command(nirslam("export /no/such/session --out '" + fresh_dir("export_missing").string() + "/x'"));
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("/no/such/session"), std::string::npos) << r.output;
}

// The report in a real browser: headless Chromium renders report.html to a PNG, and the plots
// show in it (white plot panels with coloured curves on the grey-blue page).
TEST(ExportCommand, TheReportOpensInHeadlessChromiumAndShowsThePlots) {
  if (!fs::exists("/usr/bin/chromium")) GTEST_SKIP() << "/usr/bin/chromium is not installed (packaging/install-deps.sh)";
  const fs::path dir = fresh_dir("export_report");
  const fs::path out = dir / "tunnel";
  ASSERT_EQ(run_command(nirslam("export '" + recorded_tunnel().string() + "' --out '" + out.string() + "'")).exit_code, 0);
  const fs::path screenshot = dir / "report.png";
  const CommandResult browser = run_command(
      "/usr/bin/chromium --headless --no-sandbox --disable-gpu --disable-quic --no-first-run "
      "--disable-background-networking --disable-component-update --disable-sync --user-data-dir='" +
      (dir / "profile").string() + "' --screenshot='" + screenshot.string() +
      "' --window-size=1200,1600 'file://" + (out / "report.html").string() + "'");
  ASSERT_TRUE(fs::exists(screenshot)) << browser.output;
  const cv::Mat page = nirslam::read_image(screenshot, nirslam::ImageReadMode::Bgr);
  ASSERT_EQ(page.cols, 1200);
  ASSERT_EQ(page.rows, 1600);
  int page_background = 0, plot_white = 0, coloured = 0;
  for (int y = 0; y < page.rows; ++y) {
    for (int x = 0; x < page.cols; ++x) {
      const cv::Vec3b p = page.at<cv::Vec3b>(y, x);
      if (p == cv::Vec3b(245, 241, 238)) ++page_background;  // #eef1f5
      if (p == cv::Vec3b(255, 255, 255)) ++plot_white;
      const int spread = std::max({p[0], p[1], p[2]}) - std::min({p[0], p[1], p[2]});
      if (spread > 80) ++coloured;
    }
  }
  const double area = static_cast<double>(page.total());
  EXPECT_GT(page_background / area, 0.05) << "the page itself shows";
  EXPECT_GT(plot_white / area, 0.25) << "the plot panels fill much of the page";
  EXPECT_GT(coloured, 2000) << "the curves and colour maps are drawn, not blank images";
  std::printf("report screenshot: %s\n", screenshot.string().c_str());
}

}  // namespace
}  // namespace nirslam::testing
