// Compiled by ctest (not built): a GDOS log call whose arguments do not match its
// format must not compile, and the compiler's message must name the problem.
// -DGDOS_CASE=N picks the case; case 0 is the control and must compile.
#include "rack/core/gdos.h"

void f(const rack::gdos::LogSource& src, long value) {
  using rack::gdos::Level;
#if GDOS_CASE == 0
  rack::gdos::log(src, Level::kInfo, "%ld items, %.3f m, %s", value, 0.5, "ok");
#elif GDOS_CASE == 1
  rack::gdos::log(src, Level::kInfo, "%f m", 3);  // an int for %f: RACK's GDOS printed garbage
#elif GDOS_CASE == 2
  rack::gdos::log(src, Level::kInfo, "%d items", value);  // a long for %d
#elif GDOS_CASE == 3
  rack::gdos::log(src, Level::kInfo, "%d and %d", 1);  // one argument missing
#elif GDOS_CASE == 4
  rack::gdos::log(src, Level::kInfo, "%n", &value);  // %n is refused
#endif
}
