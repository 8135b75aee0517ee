// The LCM URL the project's processes use unless told otherwise.
#pragma once

#include <string>

namespace ld {

/// $LCM_DEFAULT_URL when set; otherwise LCM's default multicast group with
/// ttl=0 (nothing leaves this host) and an 8 MiB receive buffer, so that
/// large images are not dropped by the kernel (raise net.core.rmem_max to
/// let it take effect; see README).
std::string defaultLcmUrl();

}  // namespace ld
