#include "mtcal/acquisition/run_clock.h"

namespace mtcal::acquisition {

namespace {
class RealTime final : public RunClock {
 public:
  void advanceTo(double) override {}
  std::optional<double> nowS() const override { return std::nullopt; }
};
}  // namespace

RunClock& realTime() {
  static RealTime clock;
  return clock;
}

}  // namespace mtcal::acquisition
