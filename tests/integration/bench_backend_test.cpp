// `certislam bench backend --json` end to end on a real 2-D file: every kernel variant is timed,
// ratios are relative to each kernel's first variant, and bad input names what was wrong.
#include <gtest/gtest.h>

#include <map>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/data_paths.h"
#include "tests/integration/shell.h"

namespace certislam {
namespace {

using testing::Shell;

std::string Intel() { return test_data::G2oPath("intel.g2o"); }

TEST(BenchBackend, JsonTimesEveryKernelVariantOnARealFile) {
    const auto result = Shell(std::string(CERTISLAM_BINARY) + " bench backend " + Intel() +
                              " --rank 2 --batches 1 --json");
    ASSERT_EQ(result.exit_code, 0) << result.out;
    const auto j = nlohmann::json::parse(result.out);
    EXPECT_EQ(j.at("poses").get<int>(), 1728);  // intel.g2o: vertices 0..1727
    std::map<std::string, int> variants;
    std::map<std::string, bool> first_seen;
    for (const auto& row : j.at("kernels")) {
        const std::string kernel = row.at("kernel");
        ++variants[kernel];
        EXPECT_GT(row.at("ms").get<double>(), 0.0) << row.dump();
        if (!first_seen[kernel]) {
            EXPECT_EQ(row.at("ratio").get<double>(), 1.0) << row.dump();
            first_seen[kernel] = true;
        } else {
            EXPECT_GT(row.at("ratio").get<double>(), 0.0) << row.dump();
        }
    }
    EXPECT_EQ(variants["V Q"], 3);
    EXPECT_EQ(variants["tangent projection"], 2);
    EXPECT_EQ(variants["preconditioner"], 3);
}

TEST(BenchBackend, BadInputIsAnErrorNamingIt) {
    const auto missing =
        Shell(std::string(CERTISLAM_BINARY) + " bench backend /nonexistent/x.g2o 2>&1");
    EXPECT_NE(missing.exit_code, 0);
    EXPECT_NE(missing.out.find("/nonexistent/x.g2o"), std::string::npos) << missing.out;
    const auto low_rank =
        Shell(std::string(CERTISLAM_BINARY) + " bench backend " + Intel() + " --rank 1 2>&1");
    EXPECT_NE(low_rank.exit_code, 0);
    EXPECT_NE(low_rank.out.find("--rank 1"), std::string::npos) << low_rank.out;
}

}  // namespace
}  // namespace certislam
