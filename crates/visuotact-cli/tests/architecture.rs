//! ARCHITECTURE.md's checkable claims, checked: a row per crate and a crate per row, each
//! crate's dependencies above its row, rows of at most 25 words, no document line over 120
//! characters, the command line's source
//! under the line count it states, no public function returning `Result<_, String>`, no error
//! type that is a `String` newtype (one left, listed), and no command module importing another.
//! Also docs/failure.md's promises: each names the tests that check it, and those exist.

use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// Every `.rs` file under `dir`, recursively.
fn rust_files(dir: &Path) -> Vec<PathBuf> {
    files_ending(dir, "rs")
}

/// Every file named `*.ext` under `dir`, recursively, leaving out build outputs (`target`)
/// and hidden folders (`.git`, virtual environments).
fn files_ending(dir: &Path, ext: &str) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_name().unwrap_or_default().to_string_lossy();
        if p.is_dir() {
            if name != "target" && name != "node_modules" && !name.starts_with('.') {
                out.extend(files_ending(&p, ext));
            }
        } else if p.extension().is_some_and(|x| x == ext) {
            out.push(p);
        }
    }
    out
}

/// No line of any Markdown document is over 120 characters: tables too wide for that become
/// lists, long commands are continued with `\`.
#[test]
fn no_doc_line_is_over_120_characters() {
    let mut long = Vec::new();
    for file in files_ending(&root(), "md") {
        let text = std::fs::read_to_string(&file).unwrap();
        for (n, line) in text.lines().enumerate() {
            let chars = line.chars().count();
            if chars > 120 {
                long.push(format!("{}:{}: {chars} characters", file.display(), n + 1));
            }
        }
    }
    assert!(long.is_empty(), "{long:#?}");
}

fn architecture() -> String {
    std::fs::read_to_string(root().join("ARCHITECTURE.md")).unwrap()
}

#[test]
fn the_crate_table_has_a_short_row_per_crate() {
    let text = architecture();
    let rows: Vec<(String, usize)> = text
        .lines()
        .filter(|l| l.starts_with("| `visuotact"))
        .map(|l| {
            let cells: Vec<&str> = l.split(" | ").collect();
            let name = cells[0]
                .trim_start_matches("| ")
                .trim_matches('`')
                .to_string();
            let words = cells
                .last()
                .unwrap()
                .trim_end_matches(" |")
                .split_whitespace()
                .count();
            (name, words)
        })
        .collect();
    let mut crates: Vec<String> = std::fs::read_dir(root().join("crates"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    crates.sort();
    let mut named: Vec<String> = rows.iter().map(|(n, _)| n.clone()).collect();
    named.sort();
    assert_eq!(named, crates, "ARCHITECTURE.md's rows against crates/");
    for (name, words) in &rows {
        assert!(*words <= 25, "{name}: {words} words");
    }
}

#[test]
fn the_command_line_stays_under_its_stated_size() {
    let text = architecture();
    let stated: usize = text
        .split("the CLI's source stays under ")
        .nth(1)
        .and_then(|s| s.split('k').next())
        .and_then(|n| n.trim().parse().ok())
        .expect("ARCHITECTURE.md states the CLI's size as `stays under Nk`");
    let lines: usize = rust_files(&root().join("crates/visuotact-cli/src"))
        .iter()
        .map(|p| std::fs::read_to_string(p).unwrap().lines().count())
        .sum();
    assert!(
        lines < stated * 1000,
        "{lines} lines, stated under {stated}k"
    );
}

#[test]
fn no_public_function_returns_a_string_error() {
    let mut found = Vec::new();
    for file in rust_files(&root().join("crates")) {
        if file.components().any(|c| c.as_os_str() == "tests") {
            continue;
        }
        let text = std::fs::read_to_string(&file).unwrap();
        // A signature may span lines: look from each `pub fn` to its body or `;`.
        for (at, _) in text.match_indices("pub fn ") {
            let sig = &text[at..];
            let end = sig.find(['{', ';']).unwrap_or(sig.len());
            let sig: String = sig[..end].split_whitespace().collect::<Vec<_>>().join(" ");
            if sig.contains("Result<") && sig.trim_end().ends_with(", String>") {
                found.push(format!("{}: {sig}", file.display()));
            }
        }
    }
    assert!(found.is_empty(), "{found:#?}");
}

/// Error types are enums whose variants carry the values, not a message string: an error
/// newtype around a `String` (`pub struct XError(pub String)`) is refused. The one left from
/// before is listed (issue 62); the list may only shrink.
#[test]
fn errors_are_not_string_newtypes() {
    const LEFT: [&str; 0] = [];
    let mut found = Vec::new();
    for file in rust_files(&root().join("crates")) {
        let text = std::fs::read_to_string(&file).unwrap();
        for line in text.lines().map(str::trim) {
            let Some(rest) = line.strip_prefix("pub struct ") else {
                continue;
            };
            let Some((name, _)) = rest.split_once("(pub String);") else {
                continue;
            };
            if name.ends_with("Error") && !LEFT.contains(&name) {
                found.push(format!("{}: {line}", file.display()));
            }
        }
    }
    assert!(found.is_empty(), "{found:#?}");
}

#[test]
fn command_modules_never_import_each_other() {
    let dir = root().join("crates/visuotact-cli/src/commands");
    for file in rust_files(&dir) {
        let text = std::fs::read_to_string(&file).unwrap();
        for line in text.lines().map(str::trim) {
            let imports = line.contains("crate::commands::")
                || (line.contains("super::") && line != "use super::*;");
            assert!(!imports, "{}: {line}", file.display());
        }
    }
}

#[test]
fn the_pipeline_needs_the_simulator_only_for_simulated_sources() {
    let manifest =
        std::fs::read_to_string(root().join("crates/visuotact-pipeline/Cargo.toml")).unwrap();
    let deps = manifest
        .split("[dependencies]")
        .nth(1)
        .and_then(|d| d.split("\n[").next())
        .unwrap();
    let sim: Vec<&str> = deps
        .lines()
        .filter(|l| l.starts_with("visuotact-sim"))
        .collect();
    assert_eq!(sim.len(), 1, "{deps}");
    assert!(sim[0].contains("optional = true"), "{}", sim[0]);
    assert!(manifest.contains("sim = [\"dep:visuotact-sim\"]"));
    // Nothing in the pipeline names the simulator outside a `sim`-gated place or a test.
    for f in rust_files(&root().join("crates/visuotact-pipeline/src")) {
        let text = std::fs::read_to_string(&f).unwrap();
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        let (code, _tests) = text.split_once("#[cfg(test)]").unwrap_or((&text, ""));
        if name == "rig.rs" || name == "lib.rs" {
            continue; // rig.rs holds the gated rigs; lib.rs names it in its doc example
        }
        for (k, line) in code.lines().enumerate() {
            if line.contains("visuotact_sim") {
                // The gate is the item's attribute, at most two attributes above.
                let gated = code
                    .lines()
                    .skip(k.saturating_sub(3))
                    .take(k - k.saturating_sub(3) + 1)
                    .any(|l| l.contains("feature = \"sim\""));
                assert!(
                    gated,
                    "{}:{}: the simulator outside a `sim`-gated item: {line}",
                    f.display(),
                    k + 1
                );
            }
        }
    }
}

/// The crates in the order of ARCHITECTURE.md's table.
fn table_order() -> Vec<String> {
    architecture()
        .lines()
        .filter(|l| l.starts_with("| `visuotact"))
        .filter_map(|l| l.split('`').nth(1).map(str::to_string))
        .collect()
}

/// The dependencies of `deps` (crate, crate it depends on) that go down the table `order`
/// (top first) or leave it, one message each; crates outside the table are named too.
fn layering_faults(order: &[String], deps: &[(String, String)]) -> Vec<String> {
    let row = |name: &str| order.iter().position(|n| n == name);
    let mut faults = Vec::new();
    for (me, dep) in deps {
        match (row(me), row(dep)) {
            (None, _) => faults.push(format!("{me} has no row in ARCHITECTURE.md")),
            (Some(_), None) => {} // not a workspace crate
            (Some(m), Some(d)) if d >= m => faults.push(format!(
                "{me} depends on {dep}, which ARCHITECTURE.md's table puts below it"
            )),
            _ => {}
        }
    }
    faults
}

/// The check itself on a made-up graph: an upward dependency and a crate with no row are
/// faults; dependencies on crates above, or outside the workspace, are not.
#[test]
fn the_layering_check_catches_an_upward_dependency() {
    let order: Vec<String> = ["io", "vision", "cli"].map(String::from).to_vec();
    let dep = |a: &str, b: &str| (a.to_string(), b.to_string());
    let fine = [
        dep("vision", "io"),
        dep("cli", "vision"),
        dep("cli", "serde"),
    ];
    assert!(layering_faults(&order, &fine).is_empty());
    let upward = [dep("vision", "io"), dep("io", "cli"), dep("ghost", "io")];
    assert_eq!(
        layering_faults(&order, &upward),
        [
            "io depends on cli, which ARCHITECTURE.md's table puts below it",
            "ghost has no row in ARCHITECTURE.md"
        ]
    );
}

/// "Each depends only on those above it in the table": every workspace crate's normal
/// dependencies on other workspace crates, from `cargo metadata`, lie above its row.
#[test]
fn every_crate_depends_only_on_crates_above_it() {
    let out = std::process::Command::new(env!("CARGO"))
        .args([
            "metadata",
            "--format-version",
            "1",
            "--no-deps",
            "--offline",
        ])
        .current_dir(root())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "cargo metadata: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let order = table_order();
    let mut deps = Vec::new();
    for package in meta["packages"].as_array().unwrap() {
        let name = package["name"].as_str().unwrap();
        // A crate with no dependency at all still needs its row.
        deps.push((name.to_string(), name.to_string() + " (itself)"));
        for dep in package["dependencies"].as_array().unwrap() {
            // Dev- and build-dependencies are left out: tests may use any crate.
            if dep["kind"].is_null() {
                deps.push((name.to_string(), dep["name"].as_str().unwrap().to_string()));
            }
        }
    }
    assert_eq!(layering_faults(&order, &deps), Vec::<String>::new());
    let between = deps
        .iter()
        .filter(|(a, b)| order.contains(a) && order.contains(b))
        .count();
    assert!(
        between > 20,
        "only {between} dependencies between crates seen"
    );
}

/// docs/failure.md states the promises the tests check, and nothing else: every bullet of its
/// sections up to "Tests that cannot pass by skipping", and the limits table, ends with
/// `Tests: `name`, …`, and each name is a test function in the workspace (Rust `fn`, or a
/// Python test's `def`).
#[test]
fn every_promise_of_the_failure_doc_names_tests_that_exist() {
    let doc = std::fs::read_to_string(root().join("docs/failure.md")).unwrap();
    let promises = doc
        .split("## Tests that cannot pass by skipping")
        .next()
        .unwrap();
    let mut sources: Vec<String> = rust_files(&root().join("crates"))
        .iter()
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect();
    for e in std::fs::read_dir(root().join("crates/visuotact-py/tests")).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "py") {
            sources.push(std::fs::read_to_string(p).unwrap());
        }
    }
    let exists = |name: &str| {
        sources
            .iter()
            .any(|s| s.contains(&format!("fn {name}(")) || s.contains(&format!("def {name}(")))
    };
    // Bullets ("- " and their indented lines) and tables (with the `Tests:` paragraph after).
    #[derive(PartialEq)]
    enum In {
        Other,
        Bullet,
        Table,
        TableTests,
    }
    let (mut units, mut state): (Vec<String>, In) = (Vec::new(), In::Other);
    for line in promises.lines() {
        state = match state {
            _ if line.starts_with("- ") => {
                units.push(String::new());
                In::Bullet
            }
            In::Bullet if line.starts_with("  ") => In::Bullet,
            In::Table if line.starts_with('|') => In::Table,
            _ if line.starts_with('|') => {
                units.push(String::new());
                In::Table
            }
            In::Table if line.is_empty() => In::Table,
            In::Table if line.starts_with("Tests:") => In::TableTests,
            In::TableTests if !line.is_empty() => In::TableTests,
            _ => In::Other,
        };
        if state != In::Other {
            let last = units.last_mut().unwrap();
            last.push_str(line);
            last.push('\n');
        }
    }
    let units: Vec<&String> = units.iter().filter(|u| !u.is_empty()).collect();
    assert!(units.len() > 30, "{} promises found", units.len());
    for u in units {
        let tests = u
            .split("Tests: ")
            .nth(1)
            .unwrap_or_else(|| panic!("a promise names no test:\n{u}"));
        let names: Vec<&str> = tests.split('`').skip(1).step_by(2).collect();
        assert!(!names.is_empty(), "no test named in:\n{u}");
        for n in names {
            assert!(
                exists(n),
                "docs/failure.md names `{n}`, which is no test:\n{u}"
            );
        }
    }
}
