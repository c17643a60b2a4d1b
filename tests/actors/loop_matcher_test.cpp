// The loop matcher's withdrawal message (incremental PCM itself is tested in
// tests/slam/frontend/incremental_pcm_test.cpp): it round-trips and is never taken for a loop.
// The matcher's settings refuse a value that breaks their rule, naming the field.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "actors/convert.h"
#include "actors/loop_matcher_actor.h"

namespace certislam::actors {
namespace {

TEST(LoopWithdrawal, RoundTripsAndIsNotALoop) {
    const auto w = LoopWithdrawal({0, 3}, {1, 9});
    const auto ends = WithdrawnEnds(w);
    ASSERT_TRUE(ends.has_value());
    EXPECT_EQ(ends->first, (slam::PoseId{0, 3}));
    EXPECT_EQ(ends->second, (slam::PoseId{1, 9}));
    EXPECT_FALSE(FromProto(w).has_value());  // old receivers drop it as malformed
    slam::LoopClosure loop;
    loop.a = {0, 3};
    loop.b = {1, 9};
    EXPECT_FALSE(WithdrawnEnds(ToProto(loop)).has_value());
}

TEST(LoopMatcherConfig, RejectsNoRegistrationThreadsNamingTheField) {
    LoopMatcherConfig config;
    EXPECT_NO_THROW(config.Validate());
    config.registration_threads = 0;
    try {
        config.Validate();
        ADD_FAILURE() << "0 registration threads accepted";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find("LoopMatcherConfig.registration_threads = 0"),
                  std::string::npos)
            << e.what();
    }
}

}  // namespace
}  // namespace certislam::actors
