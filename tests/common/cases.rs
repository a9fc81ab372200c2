//! One test per case file. The data-driven test binaries (`harness = false` in Cargo.toml)
//! list their trials with libtest-mimic — one per input file and check — so a failing case
//! does not hide the others, and `cargo test --test golden frame_marking` runs one example.
//! The command line is cargo test's: name filters, `--exact`, `--list`, `--test-threads`.

use libtest_mimic::{Arguments, Trial};
use std::path::{Path, PathBuf};

/// A trial that runs `check`; a panic inside it (a failed `assert!`, a golden file that
/// differs) fails this trial only.
pub fn trial(name: impl Into<String>, check: impl FnOnce() + Send + 'static) -> Trial {
    Trial::test(name, move || {
        check();
        Ok(())
    })
}

/// One trial per file of `files`, named `{kind}::{stem}`; `check` gets the file's path.
pub fn per_file<F>(kind: &str, files: &[PathBuf], check: F) -> Vec<Trial>
where
    F: Fn(&Path) + Clone + Send + 'static,
{
    files
        .iter()
        .map(|f| {
            let (f, check) = (f.clone(), check.clone());
            trial(format!("{kind}::{}", stem(&f)), move || check(&f))
        })
        .collect()
}

/// A case's name: its file name without the extension.
pub fn stem(path: &Path) -> String {
    path.file_stem().unwrap().to_string_lossy().into_owned()
}

/// Runs the trials as cargo's own harness would and exits with its status.
pub fn run(trials: Vec<Trial>) -> ! {
    libtest_mimic::run(&Arguments::from_args(), trials).exit()
}
