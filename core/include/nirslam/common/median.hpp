#pragma once

// The median as the robust estimators take it: the element at n/2 of the sorted values (the upper
// one of an even count), with 1.4826 times the median absolute deviation for a standard deviation.

#include <algorithm>
#include <cstddef>
#include <vector>

namespace nirslam {

// Reorders `values`; 0 for none.
inline double median_in_place(std::vector<double>& values) {
  if (values.empty()) return 0.0;
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

// Of a copy, leaving the caller's order.
inline double median_of(std::vector<double> values) { return median_in_place(values); }

}  // namespace nirslam
