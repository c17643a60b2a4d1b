// libFuzzer's initialisation hook for the fuzzers that parse protobuf: payload strings with invalid
// UTF-8 make protobuf log an error per input, so its log is silenced to keep the output legible.
// Include from exactly one file of a fuzzer.
#pragma once

#include <google/protobuf/stubs/logging.h>

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/) {
    google::protobuf::SetLogHandler(nullptr);
    return 0;
}
