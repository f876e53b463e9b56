// Subcommands of the `furnihost` binary. Each lives in its own cmd_<name>.cpp and parses its
// own arguments with CLI11. Return value = process exit code (0 ok, 2 input error, 1 internal).
// Errors are thrown as furnihost::InputError / StageError and mapped by main().
#pragma once
#include <string>
#include <vector>

namespace furnihost::app {

// args excludes the program name and the subcommand word.
int RunDetect(const std::vector<std::string>& args);    // furnihost --graph G SCAN...
int RunPlugins(const std::vector<std::string>& args);   // furnihost plugins
int RunValidate(const std::vector<std::string>& args);  // furnihost validate
int RunTrain(const std::vector<std::string>& args);     // furnihost train
int RunSimulate(const std::vector<std::string>& args);  // furnihost simulate
int RunEval(const std::vector<std::string>& args);      // furnihost eval (A/B evaluation)
int RunCompare(const std::vector<std::string>& args);   // furnihost compare RUN_A RUN_B
int RunGap(const std::vector<std::string>& args);       // furnihost gap (training views against real parts)
int RunCatalog(const std::vector<std::string>& args);   // furnihost catalog (models, sizes, fronts)

}  // namespace furnihost::app
