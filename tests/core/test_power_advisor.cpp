// The power recommendation on synthetic sweeps with known answers: plateau reached or not, the
// clipping limit binding, the illuminator's maximum, entropy falling past its peak, a flat sweep,
// too few points (the prior stands), and the priors of the shipped configuration.

#include <cmath>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "nirslam/config/illumination_config.hpp"
#include "nirslam/illumination/advisor.hpp"

namespace nirslam {
namespace {

const std::vector<double> kTable1AndBeyond{0, 20, 40, 50, 70, 100, 125, 150};

// A sweep point of `frames` identical frames.
SweepPoint point(double power_w, double entropy_bits, double saturated, int frames = 30) {
  SweepPoint p;
  p.power_w = power_w;
  FrameMetrics m;
  m.quality.entropy_bits = entropy_bits;
  m.quality.saturated_fraction = saturated;
  m.quality.mean = 0.4;
  for (int i = 0; i < frames; ++i) p.add(m);
  return p;
}

std::vector<SweepPoint> sweep_of(const std::function<double(double)>& entropy,
                                 const std::function<double(double)>& saturated, const std::vector<double>& powers) {
  std::vector<SweepPoint> points;
  for (double p : powers) points.push_back(point(p, entropy(p), saturated(p)));
  return points;
}

bool has_reason(const Recommendation& r, const std::string& text) {
  for (const auto& reason : r.reasons)
    if (reason.find(text) != std::string::npos) return true;
  return false;
}

std::string reasons(const Recommendation& r) {
  std::string all;
  for (const auto& reason : r.reasons) all += "  " + reason + "\n";
  return all;
}

const SaturationCurve kRoom{2.0, 7.5, 20.0};
const auto kNoClipping = [](double) { return 0.0; };
// 98 % of the plateau: P = 20 ln(5.5 / (0.02 * 7.5)).
const double kRoomAnswer = 20.0 * std::log(5.5 / 0.15);

TEST(PowerAdvisor, PlateauReachedGivesTheShareOfThePlateau) {
  const auto points = sweep_of(kRoom, kNoClipping, kTable1AndBeyond);
  const Recommendation r = recommend_from_sweep(points, {}, {});
  ASSERT_EQ(r.source, RecommendationSource::Sweep) << reasons(r);
  EXPECT_NEAR(r.power_w, kRoomAnswer, 1e-3);
  EXPECT_NEAR(r.share_power_w, kRoomAnswer, 1e-3);
  EXPECT_NEAR(r.expected_share, 0.98, 1e-6);
  EXPECT_TRUE(r.plateau_reached);
  EXPECT_FALSE(r.extrapolated);
  EXPECT_FALSE(r.clipping_limited);
  EXPECT_EQ(r.confidence, Confidence::High) << reasons(r);
  EXPECT_EQ(r.points_fitted, 8);
  ASSERT_TRUE(r.expected_saturated_fraction);
  EXPECT_DOUBLE_EQ(*r.expected_saturated_fraction, 0.0);
  EXPECT_TRUE(has_reason(r, "plateau reached")) << reasons(r);
  EXPECT_TRUE(has_reason(r, "98 % of the plateau (7.35 of 7.50 bits) is reached at 72.0 W")) << reasons(r);

  // Another share, another answer: 95 %.
  const Recommendation r95 = recommend_from_sweep(points, {.plateau_share = 0.95}, {});
  EXPECT_NEAR(r95.power_w, 20.0 * std::log(5.5 / (0.05 * 7.5)), 1e-3);
}

TEST(PowerAdvisor, SweepStoppedBeforeThePlateauIsExtrapolated) {
  const auto points = sweep_of(kRoom, kNoClipping, {0, 10, 20, 30, 40, 50});
  const Recommendation r = recommend_from_sweep(points, {}, {});
  ASSERT_EQ(r.source, RecommendationSource::Sweep);
  EXPECT_NEAR(r.power_w, kRoomAnswer, 1e-2);  // exact data: the fit still finds the curve
  EXPECT_TRUE(r.extrapolated);
  EXPECT_FALSE(r.plateau_reached);
  EXPECT_FALSE(r.expected_saturated_fraction) << "saturation beyond the sweep is not measured";
  EXPECT_EQ(r.confidence, Confidence::Low);
  EXPECT_TRUE(has_reason(r, "extrapolated: the sweep stopped at 50 W")) << reasons(r);
  EXPECT_NE(r.headline().find("extrapolated"), std::string::npos);
}

TEST(PowerAdvisor, ClippingLimitBindsBelowThePlateauShare) {
  // Saturation 0 up to 40 W, then 0.1 % per W: 1 % at 50 W, 3 % at 70 W. The limit (1 %) is
  // crossed at 50 W, below the 72 W the plateau share needs.
  const auto saturated = [](double p) { return std::max(0.0, (p - 40.0) * 0.001); };
  const auto points = sweep_of(kRoom, saturated, kTable1AndBeyond);
  const Recommendation r = recommend_from_sweep(points, {}, {});
  ASSERT_EQ(r.source, RecommendationSource::Sweep);
  EXPECT_TRUE(r.clipping_limited);
  EXPECT_NEAR(r.power_w, 50.0, 1e-9);
  EXPECT_NEAR(r.expected_entropy_bits, kRoom(50.0), 1e-4);
  EXPECT_LT(r.expected_share, 0.98);
  ASSERT_TRUE(r.expected_saturated_fraction);
  EXPECT_NEAR(*r.expected_saturated_fraction, 0.01, 1e-12);
  EXPECT_TRUE(has_reason(r, "clipping limit binds")) << reasons(r);
  // With a looser limit (5 %) the crossing moves to 90 W, above the share's 72 W: the plateau decides.
  const Recommendation loose = recommend_from_sweep(points, {.max_saturated_fraction = 0.05}, {});
  EXPECT_FALSE(loose.clipping_limited);
  EXPECT_NEAR(loose.power_w, kRoomAnswer, 1e-3);
  // Between sweep points the crossing is interpolated: limit 2 % lies between 50 W (1 %) and 70 W (3 %).
  const Recommendation two = recommend_from_sweep(points, {.max_saturated_fraction = 0.02}, {});
  EXPECT_TRUE(two.clipping_limited);
  EXPECT_NEAR(two.power_w, 60.0, 1e-9);
}

TEST(PowerAdvisor, ClippedAtEveryPowerRecommendsTheLowestWithLowConfidence) {
  const auto points = sweep_of(kRoom, [](double) { return 0.05; }, kTable1AndBeyond);
  const Recommendation r = recommend_from_sweep(points, {}, {});
  EXPECT_TRUE(r.clipping_limited);
  EXPECT_DOUBLE_EQ(r.power_w, 0.0);
  EXPECT_EQ(r.confidence, Confidence::Low);
  EXPECT_TRUE(has_reason(r, "even at the lowest swept power")) << reasons(r);
}

TEST(PowerAdvisor, HeldAtTheIlluminatorsMaximum) {
  // A far scene: P_s = 60 W puts 98 % of the plateau at 216 W, beyond a 150 W lamp.
  const SaturationCurve far{1.5, 7.2, 60.0};
  const auto points = sweep_of(far, kNoClipping, kTable1AndBeyond);
  const Recommendation r = recommend_from_sweep(points, {}, {});
  EXPECT_NEAR(r.share_power_w, 60.0 * std::log(5.7 / (0.02 * 7.2)), 0.05);
  EXPECT_TRUE(r.controller_limited);
  EXPECT_DOUBLE_EQ(r.power_w, 150.0);
  EXPECT_FALSE(r.plateau_reached);
  EXPECT_TRUE(has_reason(r, "maximum of 150 W")) << reasons(r);
}

TEST(PowerAdvisor, PowerRoundsUpToTheIlluminatorsStep) {
  const auto points = sweep_of(kRoom, kNoClipping, kTable1AndBeyond);
  IlluminatorCapabilities stepped;
  stepped.step_w = 5.0;
  EXPECT_DOUBLE_EQ(recommend_from_sweep(points, {}, stepped).power_w, 75.0);  // 72.0 W rounded up
}

TEST(PowerAdvisor, PointsPastTheEntropyPeakStayOutOfTheFit) {
  // Up to 70 W the room curve; from 100 W highlights clip and entropy falls.
  const auto entropy = [](double p) { return p <= 70.0 ? kRoom(p) : kRoom(70.0) - 0.01 * (p - 70.0); };
  const auto saturated = [](double p) { return p <= 70.0 ? 0.0 : 0.002 * (p - 70.0); };
  const auto points = sweep_of(entropy, saturated, kTable1AndBeyond);
  const Recommendation r = recommend_from_sweep(points, {}, {});
  ASSERT_TRUE(r.fit);
  EXPECT_EQ(r.excluded_powers_w, (std::vector<double>{100, 125, 150}));
  EXPECT_EQ(r.points_fitted, 5);
  EXPECT_NEAR(r.fit->curve.p_s_w, 20.0, 1e-3) << "the fit sees only the rising part";
  // 1 % saturation is reached at 75 W, above the 72.0 W of the plateau share.
  EXPECT_NEAR(r.power_w, kRoomAnswer, 1e-3);
  EXPECT_TRUE(has_reason(r, "3 power(s) past the entropy peak")) << reasons(r);
}

TEST(PowerAdvisor, FlatSweepRecommendsTheLowestPower) {
  const auto points = sweep_of([](double p) { return 6.9 + 0.0002 * p; }, kNoClipping, kTable1AndBeyond);
  const Recommendation r = recommend_from_sweep(points, {}, {});
  ASSERT_EQ(r.source, RecommendationSource::Sweep);
  EXPECT_DOUBLE_EQ(r.power_w, 0.0);
  EXPECT_FALSE(r.fit);
  EXPECT_TRUE(has_reason(r, "adds nothing the camera sees")) << reasons(r);
}

TEST(PowerAdvisor, NoisySweepKeepsItsAnswerWithinTheStatedUncertainty) {
  // Per-point means of 30 frames with 0.02 bits of scatter each.
  std::vector<SweepPoint> points;
  unsigned state = 12345;
  const auto uniform = [&state] {
    state = state * 1103515245u + 12345u;
    return static_cast<double>((state >> 8) & 0xFFFF) / 65535.0 - 0.5;
  };
  for (double p : kTable1AndBeyond) {
    SweepPoint sp;
    sp.power_w = p;
    for (int i = 0; i < 30; ++i) {
      FrameMetrics m;
      m.quality.entropy_bits = kRoom(p) + 0.07 * uniform();  // sd 0.02
      sp.add(m);
    }
    points.push_back(sp);
  }
  const Recommendation r = recommend_from_sweep(points, {}, {});
  ASSERT_TRUE(r.low_w && r.high_w);
  const double sigma = 0.5 * (*r.high_w - *r.low_w);
  EXPECT_GT(sigma, 0.0);
  EXPECT_LT(std::abs(r.power_w - kRoomAnswer), 4.0 * sigma + 0.5) << reasons(r);
  EXPECT_NE(r.confidence, Confidence::Low) << reasons(r);
}

TEST(PowerAdvisor, PriorStandsUntilTheSweepHasEnoughPowers) {
  const IlluminationConfig config =
      load_illumination_config(std::filesystem::path(NIRSLAM_SOURCE_DIR) / "config/illumination.yaml");
  const SceneType* room = find_scene(config.scenes, "indoor");
  ASSERT_NE(room, nullptr);
  EXPECT_EQ(room->name, "room");
  const auto few = sweep_of(kRoom, kNoClipping, {0, 40, 100});
  const Recommendation prior = advise(few, room, config.advisor, config.illuminator);
  EXPECT_EQ(prior.source, RecommendationSource::Prior);
  EXPECT_DOUBLE_EQ(prior.power_w, 75.0);
  EXPECT_EQ(prior.low_w, 50.0);
  EXPECT_EQ(prior.high_w, 100.0);
  EXPECT_EQ(prior.confidence, Confidence::Low);
  EXPECT_TRUE(has_reason(prior, "sweep: 3 of the 4 powers needed")) << reasons(prior);
  EXPECT_TRUE(has_reason(prior, "source: the paper")) << reasons(prior);
  // One more power and the sweep takes over.
  auto enough = few;
  enough.push_back(point(70, kRoom(70), 0.0));
  EXPECT_EQ(advise(enough, room, config.advisor, config.illuminator).source, RecommendationSource::Sweep);
  // An assumption is labelled as one.
  const Recommendation tunnel = advise({}, find_scene(config.scenes, "tunnel"), config.advisor, config.illuminator);
  EXPECT_EQ(tunnel.source, RecommendationSource::Prior);
  EXPECT_TRUE(has_reason(tunnel, "project assumption")) << reasons(tunnel);
  // No prior, no sweep: nothing to recommend, and it says why.
  SceneType bare{"lab", "Lab", {}, std::nullopt};
  const Recommendation none = advise({}, &bare, config.advisor, config.illuminator);
  EXPECT_EQ(none.source, RecommendationSource::None);
  EXPECT_TRUE(has_reason(none, "no prior range")) << reasons(none);
}

TEST(PowerAdvisor, ShippedPriorsFollowThePapersPattern) {
  const IlluminationConfig config =
      load_illumination_config(std::filesystem::path(NIRSLAM_SOURCE_DIR) / "config/illumination.yaml");
  const auto prior = [&](const char* name) { return *find_scene(config.scenes, name)->prior; };
  EXPECT_EQ(prior("room").low_w, 50.0);
  EXPECT_EQ(prior("room").high_w, 100.0);
  EXPECT_EQ(prior("room").basis, PriorBasis::Paper);
  EXPECT_GE(prior("outdoor").low_w, 100.0);
  EXPECT_EQ(prior("outdoor").basis, PriorBasis::Paper);
  EXPECT_EQ(prior("parking").basis, PriorBasis::Assumption);
  EXPECT_EQ(prior("tunnel").basis, PriorBasis::Assumption);
  EXPECT_GT(prior("outdoor").centre_w(), prior("room").centre_w());
  // The sweep plan holds the paper's Table 1 powers.
  for (double p : {0.0, 20.0, 40.0, 50.0, 70.0, 100.0})
    EXPECT_NE(std::find(config.sweep.powers_w.begin(), config.sweep.powers_w.end(), p), config.sweep.powers_w.end()) << p;
}

}  // namespace
}  // namespace nirslam
