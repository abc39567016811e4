// A producer of the wrong sample type, for consumers' bad-input tests: it publishes a
// ServoDriveData every cycle, registered under whatever class the consumer expects
// (a "ladar" for Scan3D, a "camera" for ObjRecogCamera). Test code: priority 0.
#pragma once

#include "rack/core/data_component.h"
#include "rack/interfaces/devices.h"
#include "rack/rt/clock.h"

namespace rack::test {

class WrongTypeProducer final : public DataComponent<interfaces::ServoDriveData> {
 public:
  WrongTypeProducer() : DataComponent(DataTaskMode::kPeriodic) {}

 protected:
  HookResult loop() override {
    interfaces::ServoDriveData d{};
    publish(d, rt::host_time_ns());
    return HookResult::kOk;
  }
};

}  // namespace rack::test
