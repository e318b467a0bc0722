#include "nirslam/illumination/advisor.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>

#include <spdlog/fmt/fmt.h>

namespace nirslam {

const char* to_string(PriorBasis basis) {
  switch (basis) {
    case PriorBasis::Paper: return "paper";
    case PriorBasis::Assumption: return "assumption";
  }
  return "unknown";
}

const char* to_string(RecommendationSource source) {
  switch (source) {
    case RecommendationSource::None: return "none";
    case RecommendationSource::Prior: return "prior";
    case RecommendationSource::Sweep: return "sweep";
  }
  return "unknown";
}

const char* to_string(Confidence confidence) {
  switch (confidence) {
    case Confidence::None: return "none";
    case Confidence::Low: return "low";
    case Confidence::Medium: return "medium";
    case Confidence::High: return "high";
  }
  return "unknown";
}

namespace {

bool same_name(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) == std::tolower(static_cast<unsigned char>(y));
         });
}

std::string percent(double fraction, int decimals = 2) { return fmt::format("{:.{}f} %", 100.0 * fraction, decimals); }

// The saturated fraction between sweep points, linear in power; the first point's value below the
// sweep, std::nullopt above it (not measured).
std::optional<double> saturation_at(std::span<const SweepPoint> points, double power_w) {
  if (points.empty() || power_w > points.back().power_w + 1e-9) return std::nullopt;
  if (power_w <= points.front().power_w) return points.front().saturated_fraction.mean;
  for (std::size_t i = 1; i < points.size(); ++i) {
    if (power_w > points[i].power_w) continue;
    const SweepPoint& a = points[i - 1];
    const SweepPoint& b = points[i];
    const double t = (power_w - a.power_w) / (b.power_w - a.power_w);
    return a.saturated_fraction.mean + t * (b.saturated_fraction.mean - a.saturated_fraction.mean);
  }
  return points.back().saturated_fraction.mean;
}

// The lowest power at which the interpolated saturated fraction exceeds `limit`: the end of the
// powers that may be recommended. +infinity when no swept power exceeds it.
double first_clipping_power(std::span<const SweepPoint> points, double limit) {
  if (points.front().saturated_fraction.mean > limit) return points.front().power_w;
  for (std::size_t i = 1; i < points.size(); ++i) {
    const double before = points[i - 1].saturated_fraction.mean;
    const double after = points[i].saturated_fraction.mean;
    if (after <= limit) continue;
    const double t = (limit - before) / (after - before);
    return points[i - 1].power_w + t * (points[i].power_w - points[i - 1].power_w);
  }
  return std::numeric_limits<double>::infinity();
}

// Standard error of a point's mean entropy.
double standard_error(const SweepPoint& p) {
  return p.frames > 1 ? p.entropy_bits.stddev() / std::sqrt(static_cast<double>(p.frames)) : 0.0;
}

}  // namespace

const SceneType* find_scene(std::span<const SceneType> scenes, std::string_view name) {
  for (const SceneType& scene : scenes) {
    if (same_name(scene.name, name)) return &scene;
    for (const std::string& alias : scene.aliases)
      if (same_name(alias, name)) return &scene;
  }
  return nullptr;
}

std::string Recommendation::headline() const {
  switch (source) {
    case RecommendationSource::None: return "no recommendation";
    case RecommendationSource::Prior:
      return fmt::format("{:.0f} W (prior range {:.0f}-{:.0f} W, {} confidence)", power_w, low_w.value_or(power_w),
                         high_w.value_or(power_w), to_string(confidence));
    case RecommendationSource::Sweep:
      return fmt::format("{:.0f} W (sweep{}, {} confidence)", power_w, extrapolated ? ", extrapolated" : "",
                         to_string(confidence));
  }
  return {};
}

Recommendation recommend_from_sweep(std::span<const SweepPoint> all_points, const AdvisorSettings& settings,
                                    const IlluminatorCapabilities& illuminator) {
  Recommendation rec;
  std::vector<SweepPoint> points;
  for (const SweepPoint& p : all_points)
    if (p.frames > 0) points.push_back(p);
  std::sort(points.begin(), points.end(), [](const SweepPoint& a, const SweepPoint& b) { return a.power_w < b.power_w; });
  const int needed = std::max(settings.min_sweep_points, 3);
  if (static_cast<int>(points.size()) < needed) {
    rec.reasons.push_back(fmt::format("sweep: {} of the {} powers needed for a curve fit are measured", points.size(), needed));
    return rec;
  }
  const double share = settings.plateau_share;
  const double limit = settings.max_saturated_fraction;
  rec.source = RecommendationSource::Sweep;
  rec.highest_swept_w = points.back().power_w;

  const auto [lowest, highest] = std::minmax_element(
      points.begin(), points.end(),
      [](const SweepPoint& a, const SweepPoint& b) { return a.entropy_bits.mean < b.entropy_bits.mean; });
  const double span = highest->entropy_bits.mean - lowest->entropy_bits.mean;
  if (span < settings.min_rise_bits) {
    rec.power_w = std::clamp(points.front().power_w, illuminator.min_power_w, illuminator.max_power_w);
    rec.expected_entropy_bits = points.front().entropy_bits.mean;
    rec.expected_share = 1.0;
    rec.expected_saturated_fraction = points.front().saturated_fraction.mean;
    rec.plateau_reached = true;
    rec.points_fitted = static_cast<int>(points.size());
    rec.confidence = points.size() >= 5 ? Confidence::Medium : Confidence::Low;
    rec.reasons.push_back(fmt::format(
        "entropy varies by only {:.3f} bits over {:.0f}-{:.0f} W ({:.2f}-{:.2f} bits), less than {:.2f} bits: the "
        "illuminator adds nothing the camera sees (ambient light dominates, or the lamp does not reach the scene)",
        span, points.front().power_w, points.back().power_w, lowest->entropy_bits.mean, highest->entropy_bits.mean,
        settings.min_rise_bits));
    rec.reasons.push_back(fmt::format("the lowest swept power, {:.0f} W, is recommended; check the lamp and the camera's "
                                      "exposure if the scene is dark ({:.0f} % mean grey)",
                                      rec.power_w, 100.0 * points.front().mean.mean));
    rec.reasons.push_back(fmt::format("confidence {}: {} powers measured, no curve fitted", to_string(rec.confidence),
                                      points.size()));
    return rec;
  }

  // The saturating model describes the rise. Past the entropy peak, entropy falls where highlights
  // clip; those points are not the plateau and stay out of the fit (the clipping limit handles them).
  const auto peak = std::max_element(points.begin(), points.end(), [](const SweepPoint& a, const SweepPoint& b) {
    return a.entropy_bits.mean < b.entropy_bits.mean;
  });
  std::vector<SweepPoint> rising(points.begin(), peak + 1);
  for (auto it = peak + 1; it != points.end(); ++it) {
    const double tolerance = std::max(0.05, 2.0 * std::max(standard_error(*it), standard_error(*peak)));
    if (it->entropy_bits.mean >= peak->entropy_bits.mean - tolerance)
      rising.push_back(*it);
    else
      rec.excluded_powers_w.push_back(it->power_w);
  }
  rec.points_fitted = static_cast<int>(rising.size());
  const double clip_start = first_clipping_power(points, limit);

  const std::vector<CurveSample> samples = entropy_samples(rising);
  rec.fit = fit_saturation_curve(samples);
  if (!rec.fit) {
    // Too few points before the peak for a curve: the best measured point within the clipping limit.
    const SweepPoint* best = nullptr;
    for (const SweepPoint& p : points)
      if (p.saturated_fraction.mean <= limit && (!best || p.entropy_bits.mean > best->entropy_bits.mean)) best = &p;
    if (!best) best = &points.front();
    rec.power_w = best->power_w;
    rec.expected_entropy_bits = best->entropy_bits.mean;
    rec.expected_share = 1.0;
    rec.expected_saturated_fraction = best->saturated_fraction.mean;
    rec.clipping_limited = best->saturated_fraction.mean > limit || clip_start < peak->power_w;
    rec.confidence = Confidence::Low;
    rec.reasons.push_back(fmt::format(
        "no curve fit: only {} powers before the entropy peak ({:.2f} bits at {:.0f} W); the best measured power within "
        "the saturation limit is {:.0f} W ({:.2f} bits, {} saturated)",
        rec.points_fitted, peak->entropy_bits.mean, peak->power_w, best->power_w, best->entropy_bits.mean,
        percent(best->saturated_fraction.mean)));
    return rec;
  }
  const SaturationFit& fit = *rec.fit;
  const SaturationCurve& curve = fit.curve;
  const double rise = std::max(std::abs(curve.h_max_bits - curve.h0_bits), 0.1);
  const std::string exponent = fit.model == CurveModel::Exponential
                                   ? fmt::format("P / {:.1f} W", curve.p_s_w)
                                   : fmt::format("(P / {:.1f} W)^{:.2f}", curve.p_s_w, curve.beta);
  rec.reasons.push_back(fmt::format(
      "fit of {} powers ({:.0f}-{:.0f} W): H(P) = {:.2f} - ({:.2f} - {:.2f}) exp(-{}) bits, RMS residual {:.3f} bits",
      rec.points_fitted, rising.front().power_w, rising.back().power_w, curve.h_max_bits, curve.h_max_bits,
      curve.h0_bits, exponent, fit.rms_residual_bits));
  if (fit.model == CurveModel::StretchedExponential && fit.exponential_rms_bits)
    rec.reasons.push_back(fmt::format(
        "stretched exponential chosen over the plain one (RMS residual {:.3f} bits) by the corrected AIC: entropy rises "
        "fast, then creeps on as far surfaces brighten",
        *fit.exponential_rms_bits));
  if (!rec.excluded_powers_w.empty())
    rec.reasons.push_back(fmt::format(
        "{} power(s) past the entropy peak ({:.2f} bits at {:.0f} W) left out of the fit: entropy falls there as pixels "
        "clip",
        rec.excluded_powers_w.size(), peak->entropy_bits.mean, peak->power_w));
  if (fit.plateau_at_bound)
    rec.reasons.push_back("the plateau was held at 8 bits, the most 256 bins can hold: the sweep shows no saturation");

  rec.share_power_w = curve.power_for_share(share);
  std::optional<double> sigma_w;
  if (fit.covariance) {
    const Eigen::Vector4d g = curve.power_for_share_jacobian(share);
    sigma_w = std::sqrt(std::max(0.0, g.dot(*fit.covariance * g)));
  }
  rec.reasons.push_back(fmt::format("{:.0f} % of the plateau ({:.2f} of {:.2f} bits) is reached at {:.1f} W{}",
                                    100.0 * share, share * curve.h_max_bits, curve.h_max_bits, rec.share_power_w,
                                    sigma_w ? fmt::format(" ± {:.1f} W", *sigma_w) : std::string()));

  double power = rec.share_power_w;
  if (power > clip_start) {
    power = clip_start;
    rec.clipping_limited = true;
    if (clip_start <= points.front().power_w)
      rec.reasons.push_back(fmt::format(
          "saturated pixels exceed the {} limit even at the lowest swept power ({:.0f} W: {}): lower the exposure or "
          "gain, then sweep again",
          percent(limit), points.front().power_w, percent(points.front().saturated_fraction.mean)));
    else
      rec.reasons.push_back(fmt::format(
          "clipping limit binds: saturated pixels pass {} at {:.1f} W, below the {:.1f} W the plateau share needs",
          percent(limit), clip_start, rec.share_power_w));
  }
  if (power > illuminator.max_power_w) {
    power = illuminator.max_power_w;
    rec.controller_limited = true;
    rec.reasons.push_back(fmt::format("held at the illuminator's maximum of {:.0f} W", illuminator.max_power_w));
  }
  power = std::max(power, illuminator.min_power_w);
  if (illuminator.step_w > 0.0) {
    const double steps = (power - illuminator.min_power_w) / illuminator.step_w;
    // Round up to reach the share, down to stay inside the clipping limit.
    const double rounded = rec.clipping_limited ? std::floor(steps + 1e-9) : std::ceil(steps - 1e-9);
    power = std::min(illuminator.min_power_w + rounded * illuminator.step_w, illuminator.max_power_w);
  }
  rec.power_w = power;
  rec.expected_entropy_bits = curve(power);
  rec.expected_share = curve.h_max_bits > 0.0 ? rec.expected_entropy_bits / curve.h_max_bits : 0.0;
  rec.expected_saturated_fraction = saturation_at(points, power);
  rec.plateau_reached = rec.share_power_w <= rec.highest_swept_w + 1e-9;
  rec.extrapolated = power > rec.highest_swept_w + 1e-9;
  if (rec.clipping_limited)
    rec.reasons.push_back(fmt::format("at {:.1f} W the fitted entropy is {:.2f} bits, {:.1f} % of the plateau", power,
                                      rec.expected_entropy_bits, 100.0 * rec.expected_share));
  if (rec.expected_saturated_fraction)
    rec.reasons.push_back(fmt::format("saturated pixels at {:.1f} W: {} (limit {}), from the sweep", power,
                                      percent(*rec.expected_saturated_fraction), percent(limit)));
  if (rec.extrapolated)
    rec.reasons.push_back(fmt::format(
        "extrapolated: the sweep stopped at {:.0f} W, before the {:.1f} W recommended; saturation there is not "
        "measured. Sweep higher to confirm",
        rec.highest_swept_w, power));
  else if (rec.plateau_reached)
    rec.reasons.push_back(fmt::format("plateau reached: the sweep went to {:.0f} W", rec.highest_swept_w));

  // Confidence from the points, the power's uncertainty, the residual and whether it was measured.
  double relative = std::numeric_limits<double>::infinity();
  if (sigma_w && !rec.clipping_limited) {
    rec.low_w = std::max(0.0, power - *sigma_w);
    rec.high_w = power + *sigma_w;
    relative = *sigma_w / std::max(power, 1.0);
  }
  const double misfit = fit.rms_residual_bits / rise;
  const bool bounded = fit.plateau_at_bound || fit.scale_at_bound;
  const bool uncertainty_known = rec.clipping_limited || sigma_w.has_value();
  const double uncertainty = rec.clipping_limited ? 0.0 : relative;
  const bool clipped_everywhere = clip_start <= points.front().power_w;
  if (rec.extrapolated || bounded || clipped_everywhere || !uncertainty_known || rec.points_fitted < 4 ||
      uncertainty > 0.25 || misfit > 0.15)
    rec.confidence = Confidence::Low;
  else if (rec.points_fitted >= 5 && uncertainty <= 0.10 && misfit <= 0.05 && (rec.plateau_reached || rec.clipping_limited))
    rec.confidence = Confidence::High;
  else
    rec.confidence = Confidence::Medium;
  rec.reasons.push_back(fmt::format(
      "confidence {}: {} powers fitted, residual {:.1f} % of the {:.2f}-bit rise, power uncertainty {}{}",
      to_string(rec.confidence), rec.points_fitted, 100.0 * misfit, rise,
      rec.clipping_limited ? std::string("set by the measured clipping")
                           : (std::isfinite(relative) ? fmt::format("{:.0f} %", 100.0 * relative) : std::string("unknown")),
      rec.extrapolated ? ", extrapolated beyond the sweep" : ""));
  return rec;
}

Recommendation recommend_from_prior(const SceneType& scene, const IlluminatorCapabilities& illuminator) {
  Recommendation rec;
  if (!scene.prior) {
    rec.reasons.push_back(fmt::format("no prior range for '{}' in the configuration: sweep the power", scene.label));
    return rec;
  }
  const PowerPrior& prior = *scene.prior;
  rec.source = RecommendationSource::Prior;
  rec.power_w = std::clamp(prior.centre_w(), illuminator.min_power_w, illuminator.max_power_w);
  rec.low_w = prior.low_w;
  rec.high_w = prior.high_w;
  rec.confidence = Confidence::Low;
  rec.reasons.push_back(fmt::format("no sweep of this scene yet: the prior range for {} is {:.0f}-{:.0f} W, its centre "
                                    "{:.0f} W is suggested",
                                    scene.label, prior.low_w, prior.high_w, rec.power_w));
  rec.reasons.push_back(prior.basis == PriorBasis::Paper
                            ? fmt::format("source: the paper ({})", prior.note)
                            : fmt::format("source: a project assumption, not a published or measured figure ({})",
                                          prior.note));
  rec.reasons.push_back("a sweep of the scene replaces this prior as soon as it has enough powers");
  return rec;
}

Recommendation advise(std::span<const SweepPoint> points, const SceneType* scene, const AdvisorSettings& settings,
                      const IlluminatorCapabilities& illuminator) {
  Recommendation from_sweep = recommend_from_sweep(points, settings, illuminator);
  if (from_sweep.source == RecommendationSource::Sweep || scene == nullptr) return from_sweep;
  Recommendation from_prior = recommend_from_prior(*scene, illuminator);
  from_prior.reasons.insert(from_prior.reasons.begin(), from_sweep.reasons.begin(), from_sweep.reasons.end());
  return from_prior;
}

}  // namespace nirslam
