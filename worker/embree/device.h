// RAII ownership of Embree objects. One EmbreeDevice per process; its error callback is
// installed before anything else can fail, so no Embree error goes unreported.
#pragma once

#include <embree3/rtcore.h>

#include <stdexcept>
#include <string>

namespace tcfarm {

class EmbreeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class EmbreeDevice {
 public:
  EmbreeDevice();
  ~EmbreeDevice();
  EmbreeDevice(const EmbreeDevice&) = delete;
  EmbreeDevice& operator=(const EmbreeDevice&) = delete;

  RTCDevice get() const { return device_; }
  // Throws EmbreeError if Embree reported an error since the last call.
  void ThrowIfError(const char* during) const;

 private:
  RTCDevice device_ = nullptr;
};

// Owns one reference to an RTCScene.
class SceneHandle {
 public:
  SceneHandle() = default;
  explicit SceneHandle(RTCScene scene) : scene_(scene) {}
  ~SceneHandle() { Reset(); }
  SceneHandle(SceneHandle&& other) noexcept : scene_(other.scene_) { other.scene_ = nullptr; }
  SceneHandle& operator=(SceneHandle&& other) noexcept {
    if (this != &other) {
      Reset();
      scene_ = other.scene_;
      other.scene_ = nullptr;
    }
    return *this;
  }
  SceneHandle(const SceneHandle&) = delete;
  SceneHandle& operator=(const SceneHandle&) = delete;

  RTCScene get() const { return scene_; }
  void Reset() {
    if (scene_) rtcReleaseScene(scene_);
    scene_ = nullptr;
  }

 private:
  RTCScene scene_ = nullptr;
};

}  // namespace tcfarm
