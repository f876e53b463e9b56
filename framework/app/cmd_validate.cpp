#include <iostream>

#include "cli_common.hpp"
#include "commands.hpp"
#include "furnihost/catalog.hpp"
#include "furnihost/config.hpp"
#include "furnihost/pipeline.hpp"

namespace furnihost::app {

int RunValidate(const std::vector<std::string>& args) {
  CLI::App app{"Validate a graph config against the plugins found and construct its stages (nothing runs).", "validate"};
  CommonOptions common;
  std::string graph;
  bool print = false, catalog = false;
  common.Add(app, false);
  app.add_option("--graph,-g", graph, "graph config (JSON)")->required();
  app.add_flag("--print", print, "print the resolved config (extends applied, every default filled)");
  app.add_flag("--catalog", catalog,
               "also load the graph's catalog and print its models as imported: id, class, mesh and size [m] "
               "(x = width, y = depth, z = height; JSON)");
  if (auto rc = Parse(app, args)) return *rc;
  common.Apply();
  auto reg = common.MakeRegistry();
  GraphConfig g = common.LoadGraph(graph, *reg);
  // Every stage is constructed too: rules between parameters (a plugin's Check) fail here, not
  // after training. A constructor's InputError is the graph's fault (exit 2).
  try {
    Pipeline pipeline(g, *reg);
  } catch (const StageError& e) {
    throw InputError(graph + ": " + e.what());
  }
  if (print) std::cout << g.resolved.dump(2) << "\n";
  else if (!catalog) std::cout << graph << ": valid (" << g.stages.size() << " stages)\n";
  if (catalog) {
    const Catalog c = LoadCatalog(g.catalog, false);
    nlohmann::json models = nlohmann::json::array();
    for (const auto& m : c.models)
      models.push_back({{"id", m.id}, {"class", m.cls}, {"mesh", m.mesh_path}, {"size", {m.size.x(), m.size.y(), m.size.z()}}});
    std::cout << nlohmann::json{{"catalog", c.path}, {"models", models}}.dump(1) << "\n";
  }
  return 0;
}

}  // namespace furnihost::app
