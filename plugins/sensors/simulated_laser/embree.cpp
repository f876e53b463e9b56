// sensors.simulated_laser: Embree loaded with dlopen from the library CMake found, and meshes added
// to its scenes.
#include "embree.hpp"

#include <dlfcn.h>

#include <type_traits>

#include "furnihost/error.hpp"

namespace furnihost::sensors {

const EmbreeApi& Embree() {
  static const EmbreeApi api = [] {
    // By soname (the linker's search path), else where CMake found it (a private install).
    void* lib = dlopen(FURNIHOST_EMBREE_SONAME, RTLD_NOW | RTLD_LOCAL);
    if (!lib) lib = dlopen(FURNIHOST_EMBREE_PATH, RTLD_NOW | RTLD_LOCAL);
    if (!lib) throw StageError(std::string("cannot load Embree (" FURNIHOST_EMBREE_PATH "): ") + dlerror(), false);
    EmbreeApi a;
    auto get = [lib](auto& fn, const char* name) {
      fn = reinterpret_cast<std::remove_reference_t<decltype(fn)>>(dlsym(lib, name));
      if (!fn) throw StageError(std::string("Embree (" FURNIHOST_EMBREE_SONAME ") lacks ") + name, false);
    };
#define FURNIHOST_EMBREE_RESOLVE(name) get(a.name, "rtc" #name);
    FURNIHOST_EMBREE_ENTRY_POINTS(FURNIHOST_EMBREE_RESOLVE)
#undef FURNIHOST_EMBREE_RESOLVE
    return a;
  }();
  return api;
}

// Whether the CPU has the instructions of Embree's kernels for `isa` (an embree_isa name):
// Embree's AVX2 kernels also use FMA3 and BMI1/2, its AVX-512 ones the Skylake-server set.
bool CpuRuns(const std::string& isa) {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_cpu_init();
  if (isa == "sse2") return __builtin_cpu_supports("sse2");
  if (isa == "sse4.2") return __builtin_cpu_supports("sse4.2");
  if (isa == "avx") return __builtin_cpu_supports("avx");
  if (isa == "avx2")
    return __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") && __builtin_cpu_supports("bmi") &&
           __builtin_cpu_supports("bmi2");
  if (isa == "avx512")
    return CpuRuns("avx2") && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512dq") &&
           __builtin_cpu_supports("avx512cd") && __builtin_cpu_supports("avx512bw") &&
           __builtin_cpu_supports("avx512vl");
  return false;
#else
  return isa == "sse2";  // Embree's NEON build maps its SSE2 kernels
#endif
}

void ThrowIfEmbreeError(RTCDevice device, const char* what) {
  const RTCError err = Embree().GetDeviceError(device);
  if (err != RTC_ERROR_NONE)
    throw StageError(std::string("embree error ") + std::to_string(static_cast<int>(err)) +
                         " while " + what,
                     /*input=*/false);
}

// Adds a triangle mesh transformed by `pose` under geometry id `id`.
void AddMesh(RTCDevice device, RTCScene scene, const Mesh& mesh, const Eigen::Isometry3f& pose,
             unsigned id, const std::string& name) {
  if (mesh.triangles.empty()) return;
  const int nv = static_cast<int>(mesh.vertices.size());
  const EmbreeApi& e = Embree();
  RTCGeometry g = e.NewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  auto* v = static_cast<float*>(e.SetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0,
                                                        RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                                        mesh.vertices.size()));
  auto* t = static_cast<unsigned*>(e.SetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0,
                                                           RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                                           mesh.triangles.size()));
  if (!v || !t) {
    e.ReleaseGeometry(g);
    ThrowIfEmbreeError(device, "allocating geometry buffers");
    throw StageError("embree could not allocate buffers for " + name, false);
  }
  for (size_t i = 0; i < mesh.vertices.size(); ++i) {
    const Eigen::Vector3f w = pose * mesh.vertices[i];
    if (!w.allFinite()) {
      e.ReleaseGeometry(g);
      throw StageError(name + ": non-finite vertex " + std::to_string(i));
    }
    v[3 * i] = w.x();
    v[3 * i + 1] = w.y();
    v[3 * i + 2] = w.z();
  }
  for (size_t i = 0; i < mesh.triangles.size(); ++i) {
    const auto& tri = mesh.triangles[i];
    for (int k = 0; k < 3; ++k) {
      if (tri[k] < 0 || tri[k] >= nv) {
        e.ReleaseGeometry(g);
        throw StageError(name + ": triangle " + std::to_string(i) + " indexes vertex " +
                         std::to_string(tri[k]) + " of " + std::to_string(nv));
      }
      t[3 * i + k] = static_cast<unsigned>(tri[k]);
    }
  }
  e.CommitGeometry(g);
  e.AttachGeometryByID(scene, g, id);
  e.ReleaseGeometry(g);  // the scene holds it
  ThrowIfEmbreeError(device, ("adding " + name).c_str());
}

}  // namespace furnihost::sensors
