// Writes the seed corpus of the envelope fuzzer: real encoded messages of every schema type
// (fields filled through reflection), with inline and shared-memory frames, plus the rejected
// shapes the decoder must count (other major version, newer minor with unknown fields).
// Usage: envelope_fuzz_seeds OUT_DIR
#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "tests/fuzz/fuzz_frames.h"
#include "tests/fuzz/fuzz_types.h"
#include "transport/message.h"

namespace certislam::fuzz {
namespace {

using google::protobuf::FieldDescriptor;
using google::protobuf::Message;

// Sets one scalar field (or appends to a repeated one) with a value derived from seed.
void SetScalar(Message& message, const FieldDescriptor& field, int seed) {
    const auto* r = message.GetReflection();
    const bool rep = field.is_repeated();
    switch (field.cpp_type()) {
        case FieldDescriptor::CPPTYPE_INT32:
            rep ? r->AddInt32(&message, &field, -seed) : r->SetInt32(&message, &field, -seed);
            break;
        case FieldDescriptor::CPPTYPE_INT64:
            rep ? r->AddInt64(&message, &field, 1'700'000'000'000'000'000 + seed)
                : r->SetInt64(&message, &field, 1'700'000'000'000'000'000 + seed);
            break;
        case FieldDescriptor::CPPTYPE_UINT32:
            rep ? r->AddUInt32(&message, &field, seed) : r->SetUInt32(&message, &field, seed);
            break;
        case FieldDescriptor::CPPTYPE_UINT64:
            rep ? r->AddUInt64(&message, &field, 1000u + seed)
                : r->SetUInt64(&message, &field, 1000u + seed);
            break;
        case FieldDescriptor::CPPTYPE_DOUBLE:
            rep ? r->AddDouble(&message, &field, 0.25 * seed)
                : r->SetDouble(&message, &field, 0.25 * seed);
            break;
        case FieldDescriptor::CPPTYPE_FLOAT:
            rep ? r->AddFloat(&message, &field, 0.5f * static_cast<float>(seed))
                : r->SetFloat(&message, &field, 0.5f * static_cast<float>(seed));
            break;
        case FieldDescriptor::CPPTYPE_BOOL:
            rep ? r->AddBool(&message, &field, true) : r->SetBool(&message, &field, true);
            break;
        case FieldDescriptor::CPPTYPE_ENUM: {
            const auto* value = field.enum_type()->value(field.enum_type()->value_count() - 1);
            rep ? r->AddEnum(&message, &field, value) : r->SetEnum(&message, &field, value);
            break;
        }
        case FieldDescriptor::CPPTYPE_STRING: {
            const std::string text = "robot" + std::to_string(seed) + "/actor";
            rep ? r->AddString(&message, &field, text) : r->SetString(&message, &field, text);
            break;
        }
        case FieldDescriptor::CPPTYPE_MESSAGE:
            break;
    }
}

// Fills every field of message (repeated fields with two elements), nested messages too.
void Fill(Message& message, int seed, int depth) {
    const auto* descriptor = message.GetDescriptor();
    const auto* r = message.GetReflection();
    for (int i = 0; i < descriptor->field_count(); ++i) {
        const FieldDescriptor& field = *descriptor->field(i);
        const int count = field.is_repeated() ? 2 : 1;
        for (int k = 0; k < count; ++k) {
            if (field.cpp_type() != FieldDescriptor::CPPTYPE_MESSAGE) {
                SetScalar(message, field, seed + k + i);
            } else if (depth < 3) {
                Message* child = field.is_repeated() ? r->AddMessage(&message, &field)
                                                     : r->MutableMessage(&message, &field);
                Fill(*child, seed + k + i, depth + 1);
            }
        }
    }
}

// A message of the prototype's type wrapped in an envelope, with the given binary frames.
transport::Message Wrap(const Message& prototype, int seed,
                        std::vector<transport::SharedBuffer> frames) {
    std::unique_ptr<Message> payload(prototype.New());
    Fill(*payload, seed, 0);
    transport::Message message;
    message.envelope.set_schema_major(transport::kSchemaMajor);
    message.envelope.set_schema_minor(transport::kSchemaMinor);
    message.envelope.set_type_name(payload->GetDescriptor()->full_name());
    payload->SerializeToString(message.envelope.mutable_payload());
    for (auto& frame : frames) transport::AppendFrame(message, std::move(frame));
    return message;
}

void Write(const std::filesystem::path& dir, const std::string& name,
           const transport::Message& message) {
    std::ofstream out(dir / name, std::ios::binary);
    out << JoinFrames(transport::Encode(message));
    if (!out) throw std::runtime_error("cannot write " + (dir / name).string());
}

int Run(const std::filesystem::path& dir) {
    std::filesystem::create_directories(dir);
    const std::string cloud(256, '\x3f');  // 16 XYZI points
    int seed = 1;
    for (const auto* prototype : AllMessageTypes()) {
        const std::string type = prototype->GetDescriptor()->name();
        Write(dir, type + "-plain", Wrap(*prototype, seed, {}));
        Write(dir, type + "-frame",
              Wrap(*prototype, seed + 1, {transport::SharedBuffer::Copy(cloud.data(), 64)}));
        ++seed;
    }
    v1::ShmDescriptor shm;
    Fill(shm, 7, 0);
    shm.set_segment_name("/certislam-123-4-abcdef");
    const std::string shm_bytes = shm.SerializeAsString();
    transport::Message with_shm = Wrap(v1::Keyframe::default_instance(), 3, {});
    transport::AppendFrame(with_shm,
                           transport::SharedBuffer::Copy(shm_bytes.data(), shm_bytes.size()),
                           v1::FRAME_KIND_SHM_DESCRIPTOR);
    Write(dir, "Keyframe-shm", with_shm);
    transport::Message future = Wrap(v1::Heartbeat::default_instance(), 9, {});
    future.envelope.set_schema_major(transport::kSchemaMajor + 1);
    Write(dir, "Heartbeat-major2", future);
    transport::Message newer = Wrap(v1::Heartbeat::default_instance(), 9, {});
    newer.envelope.set_schema_minor(transport::kSchemaMinor + 1);
    newer.envelope.GetReflection()->MutableUnknownFields(&newer.envelope)->AddVarint(99, 12345);
    Write(dir, "Heartbeat-minor1-unknown-field", newer);
    std::printf("wrote %d seeds to %s\n", 2 * static_cast<int>(AllMessageTypes().size()) + 3,
                dir.c_str());
    return 0;
}

}  // namespace
}  // namespace certislam::fuzz

int main(int argc, char** argv) {
    if (argc != 2) {
        std::fprintf(stderr, "usage: %s OUT_DIR\n", argv[0]);
        return 2;
    }
    return certislam::fuzz::Run(argv[1]);
}
