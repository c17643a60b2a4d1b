// One spelling of the certificate's verdict and path in every output of the command: lower-case
// words ("certified", "not optimal", "not critical", "inconclusive"; "distributed", ...).
#pragma once

#include <string>

#include "certislam/v1/certificate.pb.h"

namespace certislam::bin {

/// "certified", "not optimal", "not critical", "inconclusive" (certify::VerdictName, through
/// actors::VerdictName) or "none" (no certificate yet).
std::string VerdictName(v1::CertificateVerdict verdict);

/// "centralised", "distributed", "fallback" or "none".
std::string CertificatePathName(v1::CertificatePath path);

}  // namespace certislam::bin
