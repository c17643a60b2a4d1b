// The certislam.v1 top-level message types, for the fuzzer and its seed writer: referencing each
// default instance links its generated code and registers it in the generated descriptor pool.
#pragma once

#include <google/protobuf/message.h>

#include <vector>

#include "certislam/v1/certificate.pb.h"
#include "certislam/v1/control.pb.h"
#include "certislam/v1/envelope.pb.h"
#include "certislam/v1/keyframe.pb.h"
#include "certislam/v1/loop_closure.pb.h"
#include "certislam/v1/map.pb.h"
#include "certislam/v1/rbcd.pb.h"
#include "certislam/v1/scan_context.pb.h"

namespace certislam::fuzz {

/// One default instance per top-level message type of the schemas.
inline std::vector<const google::protobuf::Message*> AllMessageTypes() {
    return {&v1::Keyframe::default_instance(),
            &v1::CloudRequest::default_instance(),
            &v1::CloudReply::default_instance(),
            &v1::ScanContextDescriptor::default_instance(),
            &v1::LoopClosureCandidate::default_instance(),
            &v1::LoopClosure::default_instance(),
            &v1::PublicPoses::default_instance(),
            &v1::SolverStatus::default_instance(),
            &v1::TrajectoryUpdate::default_instance(),
            &v1::CertificateVector::default_instance(),
            &v1::CertificateReport::default_instance(),
            &v1::MapUpdate::default_instance(),
            &v1::Hello::default_instance(),
            &v1::Ready::default_instance(),
            &v1::Heartbeat::default_instance(),
            &v1::Shutdown::default_instance(),
            &v1::ShmDescriptor::default_instance()};
}

}  // namespace certislam::fuzz
