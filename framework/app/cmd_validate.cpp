#include <iostream>

#include "cli_common.hpp"
#include "commands.hpp"
#include "furnihost/config.hpp"

namespace furnihost::app {

int RunValidate(const std::vector<std::string>& args) {
  CLI::App app{"Validate a graph config against the plugins found (nothing runs).", "validate"};
  CommonOptions common;
  std::string graph;
  bool print = false;
  common.Add(app, false);
  app.add_option("--graph,-g", graph, "graph config (JSON)")->required();
  app.add_flag("--print", print, "print the resolved config (extends applied, every default filled)");
  if (auto rc = Parse(app, args)) return *rc;
  common.Apply();
  auto reg = common.MakeRegistry();
  GraphConfig g = LoadGraph(graph, *reg);
  if (print) std::cout << g.resolved.dump(2) << "\n";
  else std::cout << graph << ": valid (" << g.stages.size() << " stages)\n";
  return 0;
}

}  // namespace furnihost::app
