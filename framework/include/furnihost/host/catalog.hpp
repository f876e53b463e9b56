// CAD catalogs (catalog.json, the schema of ../shared/data/cad_catalog/catalog.json):
//   {"frame": "...", "models": [{"id", "class", "subclass"?, "mesh", "up": "+y",
//     exactly one of "scale" (m per unit) | "height_m" | "size_m": [width, depth, height],
//     "front"?: "+z" | [x, y, z]}]}
// Meshes are read with assimp, triangulated, turned z up, scaled to metres and placed with
// their bounding-box bottom centre at the origin.
// "front" names the way the model faces (a chair's open side, a sofa's seat side, a cabinet's
// doors) in the mesh file's own axes, as "up" does. A model without one gets the estimate of
// EstimateFront, and the catalog's load logs which models it estimated and how.
#pragma once
#include <map>
#include <string>
#include <vector>

#include "furnihost/types.hpp"

namespace furnihost {

struct CatalogIssue {
  std::string id;      // model id (or "#<index>" when it has none)
  std::string reason;  // one line
};

// The way a model faces: a unit vector of its catalog frame (z up), horizontal.
struct ModelFront {
  Eigen::Vector3f front = -Eigen::Vector3f::UnitY();
  // "catalog" when catalog.json gives it, else "estimated ..." with the depths it was chosen on.
  std::string source;
};

struct FURNIHOST_API Catalog {
  std::string path;
  std::string hash;    // hex digest of catalog.json and every mesh file (model cache key)
  std::vector<CatalogModel> models;
  std::vector<CatalogIssue> skipped;
  std::map<std::string, ModelFront> fronts;  // model id -> the way it faces (every loaded model)

  const CatalogModel* Find(const std::string& id) const;
  const ModelFront* FrontOf(const std::string& id) const;  // null for an unknown id
  std::vector<std::string> Classes() const;  // sorted, unique
};

// The median extents of each class's models in the catalog (per axis).
FURNIHOST_API std::map<std::string, Eigen::Vector3f> TypicalClassSizes(const Catalog& catalog);

// strict: the first invalid entry throws InputError "<catalog>: model <id>: <reason>";
// otherwise invalid entries are skipped, listed in `skipped` and logged as warnings.
FURNIHOST_API Catalog LoadCatalog(const std::string& path, bool strict = false);

// The way a model (its mesh in the catalog frame: z up, bounding-box bottom centre at the
// origin) faces, from its shape: per horizontal axis, how much deeper rays along it look into
// the mesh from one end than from the other before they meet its surface (a chair's seat, a
// sofa's, a bookcase's shelves, a desk's knee space are open to the front), less how far its
// top quarter stands towards that end (a seat's back, a desk's hutch stand at the back); the
// axis and end that score highest. Long furniture (one side 1.3 times the other) faces across
// its length. Ambiguous (no end ahead by 0.03: a closed chest, a table): -y, or -x across a
// length along y.
struct FrontEstimate {
  Eigen::Vector3f front = -Eigen::Vector3f::UnitY();  // unit, z = 0
  bool ambiguous = false;
  std::string how;  // one line: the direction and the depths it was chosen on
};
FURNIHOST_API FrontEstimate EstimateFront(const Mesh& mesh);

// The way an object faces [rad about +z, counter-clockwise from +x] when its model, whose front
// is `front` (model frame), stands at `model_pose` (model -> world).
FURNIHOST_API float FacingYaw(const Eigen::Isometry3f& model_pose, const Eigen::Vector3f& front);
// Detection::yaw of every detection with a placed model of `catalog` (a model_pose other than
// the identity): the way that model's front faces, whichever model it is.
FURNIHOST_API void SetFacing(std::vector<Detection>& detections, const Catalog& catalog);

// Loads one mesh file with assimp (all formats it reads), triangulated, node transforms baked,
// in file units and axes. InputError on failure.
FURNIHOST_API Mesh LoadMeshFile(const std::string& path);

}  // namespace furnihost
