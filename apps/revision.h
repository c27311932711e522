#pragma once
// The git revision this `lifmcr` was built from (`git describe --always
// --dirty`), or "unknown" outside a git checkout.
//
// Why a function in a file of its own: the generated header that holds it
// (apps/git_revision.cmake) changes at every commit, and only the one small
// file that includes it is compiled again.

namespace lifmcr::apps {

const char* GitRevision();

}  // namespace lifmcr::apps
