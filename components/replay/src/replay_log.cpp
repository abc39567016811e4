#include "rack/replay/replay_log.h"

#include "rack/replay/carmen_log.h"
#include "rawlog_reader.h"

namespace rack::replay {

LoadLogResult load_replay_log(const std::string& path) {
  const bool rawlog = path.size() >= 7 && path.compare(path.size() - 7, 7, ".rawlog") == 0;
  return rawlog ? load_rawlog(path) : load_carmen_log(path);
}

}  // namespace rack::replay
