// Files earshot installs beside its library, found from where the running
// binary holding this code (libearshot.so, or an executable linked
// statically) sits: PREFIX/lib, PREFIX/lib/<multiarch> or PREFIX/bin.
#pragma once

#include <string>

namespace earshot::hrtf::detail {

/** PREFIX/<relative> for the running binary's PREFIX, when that file exists
 *  (readable, or executable when `executable`); empty otherwise. */
std::string installedFile(const std::string& relative, bool executable);

/** The prepared form of the default HRTF set that earshot builds and
 *  installs (share/earshot/prepared/`name`, made at build time by `earshot
 *  cache --prepare` under the cache's entry names): PREFIX's, or the build
 *  tree's. Empty when neither has it. */
std::string shippedPreparedFile(const std::string& name);

/** The earshot-sofa-probe HrtfSet::load runs: $EARSHOT_SOFA_PROBE,
 *  PREFIX/libexec/earshot/earshot-sofa-probe, or the build tree's. Empty
 *  when none is there. */
std::string sofaProbePath();

}  // namespace earshot::hrtf::detail
