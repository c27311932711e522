#include "apps/revision.h"

#include "apps/git_revision.h"  // generated at build time (apps/git_revision.cmake)

namespace lifmcr::apps {

const char* GitRevision() { return LIFMCR_GIT_REVISION; }

}  // namespace lifmcr::apps
