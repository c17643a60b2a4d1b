// Lower-case names of the certificate's verdicts and paths (see verdict.h).
#include "bin/verdict.h"

namespace certislam::bin {

std::string VerdictName(v1::CertificateVerdict verdict) {
    switch (verdict) {
        case v1::CERTIFICATE_VERDICT_CERTIFIED:
            return "certified";
        case v1::CERTIFICATE_VERDICT_NOT_CERTIFIED:
            return "not optimal";
        case v1::CERTIFICATE_VERDICT_INCONCLUSIVE:
            return "inconclusive";
        default:
            return "none";
    }
}

std::string CertificatePathName(v1::CertificatePath path) {
    switch (path) {
        case v1::CERTIFICATE_PATH_CENTRALISED:
            return "centralised";
        case v1::CERTIFICATE_PATH_DISTRIBUTED:
            return "distributed";
        case v1::CERTIFICATE_PATH_FALLBACK:
            return "fallback";
        default:
            return "none";
    }
}

}  // namespace certislam::bin
