#include "retrace/control/steering.h"

#include <cmath>

namespace retrace {

SteeringCommand SteerByImage(const std::vector<SteeringFeature>& features, double gain, double max_abs_x) {
  SteeringCommand command;
  double sum = 0.0;
  for (const SteeringFeature& f : features) {
    if (!(f.current.z() > 0) || !(f.target.z() > 0)) continue;
    const double x_current = f.current.x() / f.current.z();
    const double x_target = f.target.x() / f.target.z();
    if (!(std::abs(x_current) <= max_abs_x && std::abs(x_target) <= max_abs_x)) continue;
    sum += x_current - x_target;  // Segvic 2009, eq. (10)
    ++command.features;
  }
  if (command.features > 0) {
    command.angle = gain * sum / command.features;
    command.valid = true;
  }
  return command;
}

}  // namespace retrace
