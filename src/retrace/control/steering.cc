#include "retrace/control/steering.h"

namespace retrace {

SteeringCommand SteerByImage(const std::vector<SteeringFeature>& features, double gain) {
  SteeringCommand command;
  double sum = 0.0;
  for (const SteeringFeature& f : features) {
    if (!(f.current.z() > 0) || !(f.target.z() > 0)) continue;
    sum += f.current.x() / f.current.z() - f.target.x() / f.target.z();  // Segvic 2009, eq. (10)
    ++command.features;
  }
  if (command.features > 0) {
    command.angle = gain * sum / command.features;
    command.valid = true;
  }
  return command;
}

}  // namespace retrace
