#pragma once
// Which executor runs a campaign: the campaign file's "executor" block (kind local|slurm and the
// Slurm settings; a millflow campaign's loader has validated it already, other formats are checked
// here), overridden by `--executor` on the command line.
#include <nlohmann/json.hpp>
#include <string>

#include "engine/slurm_executor.hpp"

namespace millflow::cli {

struct ExecutorChoice {
  std::string kind = "local";
  engine::SlurmSettings
      slurm;  // the block's settings; run_dir, program and polling are the caller's
};

// Throws engine::InvalidInput naming a setting of the wrong type.
ExecutorChoice choose_executor(const nlohmann::json& campaign_document,
                               const std::string& kind_override);

}  // namespace millflow::cli
