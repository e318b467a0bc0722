#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace nirslam {

// What recover_session found and changed.
struct RecoveryReport {
  std::filesystem::path folder;
  bool was_unfinished = false;        // session.json said "recording"
  std::int64_t frames_kept = 0;       // journal lines whose image is complete
  int temp_files_removed = 0;         // partial writes (*.tmp) and the space reserve
  bool torn_line_cut = false;         // the journal ended in a torn or malformed line
  int entries_without_image = 0;      // journal lines whose image was missing or of the wrong size
  int images_without_entry = 0;      // images renamed into place whose journal line was not written
  std::string summary;                // one line for the operator
};

// Repairs a session a crash, power cut or full disk left in state "recording": removes partial
// files, cuts a torn journal line, keeps exactly the frames that have both a complete image and a
// journal line (removing the rest), and marks the session "recovered" with the report in
// session.json. A session that is complete or recovered is left alone (was_unfinished false).
// Throws InputError naming the file for a folder that is not a session or whose metadata is
// unreadable. Must not run on a session another process is still recording.
RecoveryReport recover_session(const std::filesystem::path& folder);

// recover_session for every direct sub-folder of `sessions_root` that holds an unfinished session
// (what the app runs on start over its sessions folder). Sessions that cannot be read are logged
// and skipped; a missing root yields an empty list.
std::vector<RecoveryReport> recover_unfinished_sessions(const std::filesystem::path& sessions_root);

}  // namespace nirslam
