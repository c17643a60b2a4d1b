// `certislam demo --scenario NAME`: an unknown scenario is refused naming the option. (The
// scenarios that should show a refused local minimum do not show one yet: issue 17.)
#include <gtest/gtest.h>
#include <unistd.h>

#include <string>

#include "tests/integration/shell.h"

namespace certislam {
namespace {

TEST(Scenarios, RejectsAnUnknownScenario) {
    const auto run = testing::Shell(std::string(CERTISLAM_BINARY) + " demo --scenario moon 2>&1");
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.out.find("--scenario"), std::string::npos) << run.out;
}

}  // namespace
}  // namespace certislam
