//! Runs every case of the bad-input catalog (`docs/bad-input.md`), which is the single
//! source of the cases: the doc and the tests cannot drift apart.

use std::path::Path;
use std::process::Command;

struct Case {
    number: String,
    name: String,
    command: String,
    exit: i32,
    message: String,
}

fn catalog() -> Vec<Case> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let doc = std::fs::read_to_string(root.join("docs/bad-input.md")).expect("docs/bad-input.md");
    doc.lines()
        .filter_map(|line| {
            let cells: Vec<&str> = line
                .split(" | ")
                .map(|c| c.trim().trim_matches('|').trim())
                .collect();
            if cells.len() != 5 || cells[0].parse::<u32>().is_err() {
                return None;
            }
            Some(Case {
                number: cells[0].to_string(),
                name: cells[1].to_string(),
                command: cells[2].trim_matches('`').to_string(),
                exit: cells[3].parse().expect("exit code"),
                message: cells[4].to_string(),
            })
        })
        .collect()
}

#[test]
fn catalog_has_at_least_30_cases_numbered_in_order() {
    let cases = catalog();
    assert!(cases.len() >= 30, "{} cases", cases.len());
    for (i, c) in cases.iter().enumerate() {
        assert_eq!(c.number, (i + 1).to_string(), "case numbering");
    }
}

#[test]
fn every_catalog_case_gives_its_message_and_exit_code() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let fx = root.join("tests/bad-input");
    let mut failures = Vec::new();
    for case in catalog() {
        let out_dir = std::env::temp_dir().join(format!(
            "coupler-atlas-bad-{}-{}",
            std::process::id(),
            case.number
        ));
        let _ = std::fs::remove_dir_all(&out_dir);
        let args: Vec<String> = case
            .command
            .split_whitespace()
            .map(|a| {
                a.replace("{fx}", fx.to_str().unwrap())
                    .replace("{out}", out_dir.to_str().unwrap())
            })
            .collect();
        let output = Command::new(env!("CARGO_BIN_EXE_coupler-atlas"))
            .args(&args)
            .output()
            .expect("runs");
        let stderr = String::from_utf8_lossy(&output.stderr).replace('`', "");
        let code = output.status.code();
        let mut problems = Vec::new();
        if code != Some(case.exit) {
            problems.push(format!("exit {code:?}, expected {}", case.exit));
        }
        if !stderr.contains(&case.message) {
            problems.push(format!("message not found: `{}`", case.message));
        }
        if stderr.contains("panicked") {
            problems.push("panicked".into());
        }
        if case.exit == 2 && out_dir.exists() {
            problems.push("wrote output for bad input".into());
        }
        if !problems.is_empty() {
            failures.push(format!(
                "#{} {} ({}): {}\n  stderr: {}",
                case.number,
                case.name,
                case.command,
                problems.join("; "),
                stderr.trim()
            ));
        }
        let _ = std::fs::remove_dir_all(&out_dir);
    }
    assert!(
        failures.is_empty(),
        "{} catalog case(s) failed:\n{}",
        failures.len(),
        failures.join("\n")
    );
}
