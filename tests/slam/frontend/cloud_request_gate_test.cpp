// The cloud-request gate: distance pre-gate, one request per place and robot pair, a failed
// registration reopens the place, a cloud fetched once is not fetched again.
#include "slam/frontend/cloud_request_gate.h"

#include <gtest/gtest.h>

namespace certislam::slam {
namespace {

using Decision = CloudRequestGate::Decision;

LoopCandidate Candidate(int qr, int qi, int mr, int mi, double distance = 0.1) {
    LoopCandidate c;
    c.query = {qr, qi};
    c.match = {mr, mi};
    c.sc_distance = distance;
    return c;
}

TEST(CloudRequestGate, OneRequestPerPlaceUntilItFails) {
    CloudRequestGate gate;  // window 10 keyframes, distance 0.2
    EXPECT_EQ(gate.Admit(Candidate(1, 50, 0, 20)), Decision::kFetch);
    EXPECT_EQ(gate.Admit(Candidate(1, 55, 0, 26)), Decision::kSkip);           // same place
    EXPECT_EQ(gate.Admit(Candidate(1, 55, 0, 31)), Decision::kFetch);          // match 11 away
    EXPECT_EQ(gate.Admit(Candidate(0, 20, 1, 50)), Decision::kFetch);          // other direction
    EXPECT_EQ(gate.Admit(Candidate(1, 90, 0, 90, 0.25)), Decision::kSkip);     // distance gate
    EXPECT_EQ(gate.Admit(Candidate(0, 90, 0, 20, 0.9)), Decision::kRegister);  // own cloud
    gate.Failed(Candidate(1, 50, 0, 20));
    EXPECT_EQ(gate.Admit(Candidate(1, 45, 0, 15)), Decision::kFetch);  // place reopened
    gate.Failed(Candidate(1, 45, 0, 15));
    EXPECT_EQ(gate.Admit(Candidate(1, 44, 0, 15)), Decision::kRegister);  // cloud 0:15 at hand
}

TEST(CloudRequestGate, WindowZeroRequestsEachCloudOnce) {
    CloudRequestGateConfig config;
    config.place_window = 0;
    CloudRequestGate gate(config);
    EXPECT_EQ(gate.Admit(Candidate(1, 5, 0, 7)), Decision::kFetch);
    EXPECT_EQ(gate.Admit(Candidate(1, 6, 0, 7)), Decision::kRegister);
    EXPECT_EQ(gate.Admit(Candidate(1, 6, 0, 7)), Decision::kSkip);
    config.place_window = -1;
    EXPECT_THROW(CloudRequestGate{config}, std::invalid_argument);
}

}  // namespace
}  // namespace certislam::slam
