#pragma once

// The NIR illuminator as the program sees it. Today the operator sets the power on the lamp's own
// dial and types the value in (ManualIlluminator); a serial or USB driver implements the same
// interface later, and the simulator and the demo source drive their own virtual lamp through it.
// Every call happens on the worker thread.

#include <memory>
#include <optional>
#include <string>

namespace nirslam {

struct IlluminatorCapabilities {
  double min_power_w = 0.0;
  double max_power_w = 150.0;
  double step_w = 0.0;       // the smallest settable change, 0 for a continuous control
  bool reads_back = false;   // whether current_power_w() is measured by the device, not just what was asked
  std::string description = "manual entry";

  // `watts` rounded to the nearest step. Throws std::out_of_range naming the range when it lies
  // outside [min_power_w, max_power_w] (or is not a number).
  double settable(double watts) const;
};

class IlluminatorController {
public:
  virtual ~IlluminatorController() = default;
  IlluminatorController() = default;
  IlluminatorController(const IlluminatorController&) = delete;
  IlluminatorController& operator=(const IlluminatorController&) = delete;

  virtual const IlluminatorCapabilities& capabilities() const = 0;
  // Sets the output; returns the power actually set (rounded to the step). Throws std::out_of_range
  // outside the capabilities, std::runtime_error when the device does not answer.
  virtual double set_power(double watts) = 0;
  // The power now, std::nullopt until it is known.
  virtual std::optional<double> current_power_w() const = 0;
};

// The operator turns the lamp and enters the value: set_power records what was entered.
class ManualIlluminator final : public IlluminatorController {
public:
  explicit ManualIlluminator(IlluminatorCapabilities capabilities = {}) : capabilities_(std::move(capabilities)) {}
  const IlluminatorCapabilities& capabilities() const override { return capabilities_; }
  double set_power(double watts) override;
  std::optional<double> current_power_w() const override { return power_w_; }

private:
  IlluminatorCapabilities capabilities_;
  std::optional<double> power_w_;
};

}  // namespace nirslam
