// The demo's report pieces shared by its driver and its JSON: a local-search run in words.
#pragma once

#include <string>
#include <vector>

#include "bin/demo/demo_mission.h"
#include "certify/pipeline/mission.h"

namespace certislam::bin {

/// One LM run of the pipeline as the report gives it (`rmse` per robot, already scored).
DemoLocalSearch LocalSearchReport(const std::string& start, const certify::LocalSearchRun& run,
                                  double certified_cost, const std::vector<double>& rmse);

}  // namespace certislam::bin
