// The job event log's texts: frames_written events, and the recorded frames no event has
// told yet (JobStore's event members are in job_event_log.cpp too).
#pragma once

#include <cstdint>
#include <vector>

#include "coordinator/jobs/job_store.h"
#include "coordinator/jobs/sqlite_database.h"

namespace tcfarm::jobs {

// The frames_written event of `frames` (not empty): their runs as message and fields.
EventDraft FramesWrittenEvent(const std::vector<int>& frames);
// The job's recorded frames that no frames_written event names, ascending.
std::vector<int> RecordedFramesNeverTold(sqlite::Database& db, uint64_t id);

}  // namespace tcfarm::jobs
