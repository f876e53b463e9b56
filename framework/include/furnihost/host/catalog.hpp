// CAD catalogs (catalog.json, the schema of ../shared/data/cad_catalog/catalog.json):
//   {"frame": "...", "models": [{"id", "class", "subclass"?, "mesh", "up": "+y",
//     exactly one of "scale" (m per unit) | "height_m" | "size_m": [width, depth, height]}]}
// Meshes are read with assimp, triangulated, turned z up, scaled to metres and placed with
// their bounding-box bottom centre at the origin.
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

struct FURNIHOST_API Catalog {
  std::string path;
  std::string hash;    // hex digest of catalog.json and every mesh file (model cache key)
  std::vector<CatalogModel> models;
  std::vector<CatalogIssue> skipped;

  const CatalogModel* Find(const std::string& id) const;
  std::vector<std::string> Classes() const;  // sorted, unique
};

// The median extents of each class's models in the catalog (per axis).
FURNIHOST_API std::map<std::string, Eigen::Vector3f> TypicalClassSizes(const Catalog& catalog);

// strict: the first invalid entry throws InputError "<catalog>: model <id>: <reason>";
// otherwise invalid entries are skipped, listed in `skipped` and logged as warnings.
FURNIHOST_API Catalog LoadCatalog(const std::string& path, bool strict = false);

// Loads one mesh file with assimp (all formats it reads), triangulated, node transforms baked,
// in file units and axes. InputError on failure.
FURNIHOST_API Mesh LoadMeshFile(const std::string& path);

}  // namespace furnihost
