// sensors.simulated_laser, private to the plugin: Embree, resolved at run time (embree.cpp), its
// devices and scenes as owning pointers, and triangle meshes added to a scene.
#pragma once

#include <embree3/rtcore.h>

#include <memory>
#include <string>

#include "furnihost/types.hpp"

namespace furnihost::sensors {

// The entry points this sensor calls, from the library CMake found (its soname). The library
// stays loaded for the process: devices and scenes may outlive any one sensor.
// Each entry point named once: EmbreeApi's member X is rtcX's address.
#define FURNIHOST_EMBREE_ENTRY_POINTS(X)                                                           \
  X(NewDevice) X(ReleaseDevice) X(GetDeviceError) X(NewScene) X(ReleaseScene) X(CommitScene)     \
  X(NewGeometry) X(SetNewGeometryBuffer) X(CommitGeometry) X(AttachGeometryByID) X(ReleaseGeometry) \
  X(Intersect16)
struct EmbreeApi {
#define FURNIHOST_EMBREE_MEMBER(name) decltype(&::rtc##name) name = nullptr;
  FURNIHOST_EMBREE_ENTRY_POINTS(FURNIHOST_EMBREE_MEMBER)
#undef FURNIHOST_EMBREE_MEMBER
};

// The entry points, loaded on first use (a StageError when Embree cannot be loaded).
const EmbreeApi& Embree();

// Whether the CPU has the instructions of Embree's kernels for `isa` (an embree_isa name):
// Embree's AVX2 kernels also use FMA3 and BMI1/2, its AVX-512 ones the Skylake-server set.
bool CpuRuns(const std::string& isa);

// Embree RAII.
struct DeviceDeleter {
  void operator()(RTCDeviceTy* d) const { Embree().ReleaseDevice(d); }
};
struct SceneDeleter {
  void operator()(RTCSceneTy* s) const { Embree().ReleaseScene(s); }
};
using DevicePtr = std::unique_ptr<RTCDeviceTy, DeviceDeleter>;
using ScenePtr = std::unique_ptr<RTCSceneTy, SceneDeleter>;

// A StageError naming `what` when the device has an error.
void ThrowIfEmbreeError(RTCDevice device, const char* what);

// Adds a triangle mesh transformed by `pose` under geometry id `id`.
void AddMesh(RTCDevice device, RTCScene scene, const Mesh& mesh, const Eigen::Isometry3f& pose,
             unsigned id, const std::string& name);

}  // namespace furnihost::sensors
