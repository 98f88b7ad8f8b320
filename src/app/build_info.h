// The commit the program was built from, for `ddhgs --version`. The
// definition is generated at build time (cmake/version.cmake) into one small
// source of its own, so that a new commit recompiles that file and relinks
// the program, nothing else.
#pragma once

namespace ddhgs::app {

// As `git describe --always --dirty --abbrev=12` names it: "c5e5ea52a497",
// "c5e5ea52a497-dirty" with edits not committed, "v1.0-3-gc5e5ea52a497" past
// a tag; "unknown" when the source tree was not a git checkout.
const char* build_commit();

}  // namespace ddhgs::app
