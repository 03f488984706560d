#include "worker/embree/device.h"

#include <cstdio>

namespace tcfarm {
namespace {

void ReportEmbreeError(void* /*userPtr*/, RTCError code, const char* message) {
  std::fprintf(stderr, "embree: error %d: %s\n", static_cast<int>(code), message ? message : "");
}

}  // namespace

EmbreeDevice::EmbreeDevice() {
  device_ = rtcNewDevice(nullptr);
  if (!device_) {
    throw EmbreeError("embree: cannot create a device (error " +
                      std::to_string(static_cast<int>(rtcGetDeviceError(nullptr))) + ")");
  }
  rtcSetDeviceErrorFunction(device_, ReportEmbreeError, nullptr);
}

EmbreeDevice::~EmbreeDevice() { rtcReleaseDevice(device_); }

void EmbreeDevice::ThrowIfError(const char* during) const {
  RTCError code = rtcGetDeviceError(device_);
  if (code != RTC_ERROR_NONE) {
    throw EmbreeError(std::string("embree: error ") + std::to_string(static_cast<int>(code)) +
                      " while " + during);
  }
}

}  // namespace tcfarm
