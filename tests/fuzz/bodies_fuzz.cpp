// libFuzzer target of the message body decoders the actors accept from peers (actors/convert.h):
// byte 0 picks the body (kBodies), the rest stands for its frames (fuzz_frames.h; frame 0 the
// protobuf payload, the others its binary frames). A decoder must never crash, and what it
// accepts must be finite and within its documented rules.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>

#include "actors/convert.h"
#include "actors/convert_descriptor.h"
#include "certify/distributed/distributed_lobpcg.h"
#include "certislam/v1/control.pb.h"
#include "tests/fuzz/fuzz_frames.h"
#include "tests/fuzz/fuzz_quiet_protobuf.h"

namespace certislam::fuzz {
namespace {

using Frames = std::vector<zmq::message_t>;

[[noreturn]] void Fail(const char* what) {
    std::fprintf(stderr, "bodies fuzz: %s\n", what);
    std::abort();
}

bool Finite(const Eigen::Isometry3d& T) { return T.matrix().allFinite(); }

// Frame 0 alone, parsed as T (the bodies without binary frames).
template <class T>
std::optional<T> Parse(const Frames& frames) {
    T payload;
    if (frames.empty() ||
        !payload.ParseFromArray(frames[0].data(), static_cast<int>(frames[0].size()))) {
        return std::nullopt;
    }
    return payload;
}

// Descriptor, loop matcher and mapper: the whole keyframe; the solver: its pose and id.
void Keyframe(const Frames& frames) {
    const auto message = BodyMessage<v1::Keyframe>(frames);
    if (!message) return;
    const auto keyframe = actors::DecodeKeyframe(*message);
    if (keyframe && (!Finite(keyframe->T_odom_sensor) || !keyframe->cloud)) {
        Fail("accepted keyframe with a non-finite pose or no cloud");
    }
    const auto proto = transport::Unpack<v1::Keyframe>(*message);
    const auto pose = proto ? actors::FromProto(proto->t_odom_base()) : std::nullopt;
    if (pose && !Finite(*pose)) Fail("accepted a non-finite keyframe pose");
    if (proto) (void)actors::FromProto(proto->pose_id());
}

void CloudReply(const Frames& frames) {
    const auto message = BodyMessage<v1::CloudReply>(frames);
    if (!message) return;
    v1::CloudReply reply;
    const auto cloud = actors::DecodeCloudReply(*message, &reply);
    if (cloud && !*cloud) Fail("accepted cloud reply without a cloud");
    if (cloud && reply.has_t_odom_base()) (void)actors::FromProto(reply.t_odom_base());
}

void CloudRequest(const Frames& frames) {
    const auto proto = Parse<v1::CloudRequest>(frames);
    const auto id = proto ? actors::FromProto(proto->pose_id()) : std::nullopt;
    if (id && (id->robot < 0 || id->index < 0)) Fail("accepted a negative pose id");
}

void Descriptor(const Frames& frames) {
    const auto proto = Parse<v1::ScanContextDescriptor>(frames);
    if (!proto) return;
    const auto sc = actors::FromProto(*proto);
    if (sc && (!sc->bins.allFinite() || !sc->ring_key.allFinite())) {
        Fail("accepted descriptor with non-finite values");
    }
}

void Loop(const Frames& frames) {
    const auto proto = Parse<v1::LoopClosure>(frames);
    if (!proto) return;
    (void)actors::WithdrawnEnds(*proto);
    const auto loop = actors::FromProto(*proto);
    if (loop && (!Finite(loop->T_a_b) || !(loop->kappa > 0) || !(loop->tau > 0))) {
        Fail("accepted loop closure with a non-finite pose or a weight not > 0");
    }
}

void Poses(const Frames& frames) {
    const auto proto = Parse<v1::PublicPoses>(frames);
    const auto poses = proto ? actors::FromProto(*proto) : std::nullopt;
    if (poses && (!poses->blocks.allFinite() ||
                  poses->blocks.cols() != 4 * static_cast<Eigen::Index>(poses->ids.size()))) {
        Fail("accepted public poses with non-finite values or a block of the wrong width");
    }
}

void Trajectory(const Frames& frames) {
    const auto proto = Parse<v1::TrajectoryUpdate>(frames);
    const auto poses = proto ? actors::TrajectoryFromProto(*proto) : std::nullopt;
    if (!poses) return;
    for (const auto& [id, T] : *poses) {
        if (!Finite(T)) Fail("accepted trajectory with a non-finite pose");
    }
}

void Status(const Frames& frames) {
    const auto proto = Parse<v1::SolverStatus>(frames);
    if (proto && actors::IsValidStatus(*proto) &&
        (!std::isfinite(proto->cost()) || !std::isfinite(proto->gradient_norm()))) {
        Fail("accepted solver status with a non-finite cost or gradient");
    }
}

void Round(const Frames& frames) {
    const auto proto = Parse<v1::CertificateRound>(frames);
    if (proto && actors::IsValidRound(*proto) && (proto->round() == 0 || proto->rank_r() < 3)) {
        Fail("accepted round 0 or a rank below 3");
    }
}

void Vector(const Frames& frames) {
    const auto proto = Parse<v1::CertificateVector>(frames);
    const auto vector = proto ? actors::FromProto(*proto) : std::nullopt;
    // One column (Lanczos) or a block of 1 to kMaxBlockSize columns (LOBPCG) per pose id.
    const auto per_column =
        vector ? static_cast<Eigen::Index>(actors::kCertificateBlock * vector->ids.size()) : 0;
    const bool columns = vector && (per_column == 0 ? vector->values.size() == 0
                                                    : vector->values.size() % per_column == 0 &&
                                                          vector->values.size() >= per_column &&
                                                          vector->values.size() / per_column <=
                                                              certify::kMaxBlockSize);
    if (vector && (!vector->values.allFinite() || vector->step < 0 || !columns)) {
        Fail("accepted certificate vector with non-finite values or a wrong count");
    }
}

void Reduction(const Frames& frames) {
    const auto proto = Parse<v1::CertificateReduction>(frames);
    const auto reduction = proto ? actors::FromProto(*proto) : std::nullopt;
    if (!reduction) return;
    for (const double v : reduction->values) {
        if (!std::isfinite(v)) Fail("accepted certificate reduction with a non-finite value");
    }
}

void Map(const Frames& frames) {
    const auto message = BodyMessage<v1::MapUpdate>(frames);
    const auto body = message ? actors::DecodeMapUpdate(*message) : std::nullopt;
    if (body && (!Finite(body->T_world_anchor) || body->anchor.robot != body->sender ||
                 (body->bytes && body->bytes->size() > actors::kMaxSubmapBytes))) {
        Fail("accepted map update with a foreign anchor, a non-finite pose or too many bytes");
    }
}

// The solver keeps a report as it comes, and a shutdown is only its type: parsing is all.
void Report(const Frames& frames) { (void)Parse<v1::CertificateReport>(frames); }

void Shutdown(const Frames& frames) { (void)Parse<v1::Shutdown>(frames); }

/// Every body an actor accepts from a peer; byte 0 of an input picks one.
constexpr void (*kBodies[])(const Frames&) = {Keyframe,   CloudReply,   Descriptor, Loop,    Poses,
                                              Trajectory, CloudRequest, Status,     Round,   Vector,
                                              Reduction,  Map,          Report,     Shutdown};

}  // namespace
}  // namespace certislam::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    using namespace certislam::fuzz;
    if (size == 0) return 0;
    const auto frames = SplitFrames({data + 1, size - 1});
    kBodies[data[0] % std::size(kBodies)](frames);
    return 0;
}
