//! Scratch folders for the fixtures a test binary shares between its tests.

use std::path::{Path, PathBuf};

/// An empty folder `<prefix>-<pid>` in the build's scratch folder (`CARGO_TARGET_TMPDIR`,
/// not the system's temporary folder), for fixtures held by a static: a static is never
/// dropped, so the folder outlives the run. Folders of the same prefix that earlier runs
/// left behind, whose process is gone, are removed first, so runs do not pile up. (Where
/// there is no `/proc` to ask, nothing else is removed.)
pub fn shared_scratch(prefix: &str) -> PathBuf {
    let root = Path::new(env!("CARGO_TARGET_TMPDIR"));
    let me = std::process::id();
    if Path::new("/proc/self").exists() {
        for entry in std::fs::read_dir(root).into_iter().flatten().flatten() {
            let name = entry.file_name();
            let pid = name
                .to_str()
                .and_then(|n| n.strip_prefix(prefix))
                .and_then(|rest| rest.strip_prefix('-'))
                .and_then(|pid| pid.parse::<u32>().ok());
            if let Some(pid) = pid {
                if pid != me && !Path::new(&format!("/proc/{pid}")).exists() {
                    let _ = std::fs::remove_dir_all(entry.path());
                }
            }
        }
    }
    let dir = root.join(format!("{prefix}-{me}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}
