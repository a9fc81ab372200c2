//! Output files and standard output as a shell user expects them: the umask and a replaced
//! file's mode respected, symbolic links written through, FIFOs and devices written in place
//! (never replaced), a killed run's temporary file cleaned up by the next write, and a closed
//! pipe ending lase quietly as it ends `cat`.

mod common;

use std::os::unix::fs::{FileTypeExt, MetadataExt, PermissionsExt};
use std::path::Path;
use std::process::{Command, Stdio};

const RECIPE: &str = "examples/frame_marking.lase";

fn lase_bin() -> &'static str {
    env!("CARGO_BIN_EXE_lase")
}

/// `lase emit RECIPE -o OUT` under `umask MASK`: (exit code, stderr).
fn emit_with_umask(mask: &str, out: &Path) -> (i32, String) {
    let o = Command::new("sh")
        .arg("-c")
        .arg(format!("umask {mask}; exec \"$0\" emit {RECIPE} -o \"$1\"",))
        .arg(lase_bin())
        .arg(out)
        .current_dir(common::root())
        .env("NO_COLOR", "1")
        .output()
        .unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn mode(p: &Path) -> u32 {
    std::fs::metadata(p).unwrap().mode() & 0o777
}

fn emitted_lines(p: &Path) -> usize {
    std::fs::read_to_string(p).unwrap().lines().count()
}

/// The NC program written to stdout, for comparing with what lands in a file.
fn expected_program() -> String {
    let (code, out, err) = common::lase(&["emit", RECIPE]);
    assert_eq!(code, 0, "{err}");
    out
}

#[test]
fn new_files_follow_the_umask() {
    let dir = tempfile::tempdir().unwrap();
    for (mask, want) in [("022", 0o644), ("002", 0o664), ("077", 0o600)] {
        let out = dir.path().join(format!("u{mask}.ngc"));
        let (code, err) = emit_with_umask(mask, &out);
        assert_eq!(code, 0, "{err}");
        assert_eq!(mode(&out), want, "umask {mask}");
    }
}

#[test]
fn a_replaced_file_keeps_its_mode_and_gets_the_new_program() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("keep.ngc");
    std::fs::write(&out, "old\n").unwrap();
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o664)).unwrap();
    let (code, err) = emit_with_umask("077", &out);
    assert_eq!(code, 0, "{err}");
    assert_eq!(mode(&out), 0o664);
    assert_eq!(std::fs::read_to_string(&out).unwrap(), expected_program());
}

#[test]
fn a_symbolic_link_is_written_through_and_stays_a_link() {
    let dir = tempfile::tempdir().unwrap();
    let real = dir.path().join("sub").join("real.ngc");
    std::fs::create_dir(real.parent().unwrap()).unwrap();
    std::fs::write(&real, "old\n").unwrap();
    let link = dir.path().join("link.ngc");
    // A relative link, resolved against the link's own folder.
    std::os::unix::fs::symlink("sub/real.ngc", &link).unwrap();
    let (code, err) = emit_with_umask("022", &link);
    assert_eq!(code, 0, "{err}");
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(std::fs::read_to_string(&real).unwrap(), expected_program());

    // A dangling link creates the file it names.
    let dangling = dir.path().join("dangling.ngc");
    std::os::unix::fs::symlink("sub/new.ngc", &dangling).unwrap();
    let (code, err) = emit_with_umask("022", &dangling);
    assert_eq!(code, 0, "{err}");
    assert!(
        std::fs::symlink_metadata(&dangling)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(emitted_lines(&dir.path().join("sub/new.ngc")) > 10);
}

#[test]
fn a_fifo_is_written_in_place_not_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let fifo = dir.path().join("nc.fifo");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read_to_string(fifo).unwrap())
    };
    let (code, err) = emit_with_umask("022", &fifo);
    assert_eq!(code, 0, "{err}");
    let got = reader.join().unwrap();
    assert_eq!(got, expected_program());
    assert!(
        std::fs::symlink_metadata(&fifo)
            .unwrap()
            .file_type()
            .is_fifo()
    );
}

#[test]
fn character_devices_are_written_not_replaced() {
    let (code, _, err) = common::lase(&["emit", RECIPE, "-o", "/dev/null"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        std::fs::symlink_metadata("/dev/null")
            .unwrap()
            .file_type()
            .is_char_device()
    );

    // /dev/full refuses every write: an error, and the node stays the device it was.
    let (code, _, err) = common::lase(&["emit", RECIPE, "-o", "/dev/full"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("cannot write /dev/full") && err.contains("No space left"),
        "{err}"
    );
    assert!(
        std::fs::symlink_metadata("/dev/full")
            .unwrap()
            .file_type()
            .is_char_device()
    );
}

#[test]
fn a_directory_is_refused_with_a_reason() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().to_string_lossy().into_owned();
    let (code, _, err) = common::lase(&["emit", RECIPE, "-o", &p]);
    assert_eq!(code, 1);
    assert!(err.contains("it is a directory"), "{err}");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "nothing left behind"
    );
}

#[test]
fn a_killed_runs_temporary_file_is_removed_by_the_next_write() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("job.ngc");
    // A temporary file of a process that no longer runs (above the kernel's pid range), one
    // of a live process (this test's), and a file of the user's that merely looks alike.
    let stale = dir.path().join(".job.ngc.lase-4194399.tmp");
    let live = dir
        .path()
        .join(format!(".job.ngc.lase-{}.tmp", std::process::id()));
    let users = dir.path().join(".job.ngc.lase-notes.tmp");
    for p in [&stale, &live, &users] {
        std::fs::write(p, "partial").unwrap();
    }
    let (code, err) = emit_with_umask("022", &out);
    assert_eq!(code, 0, "{err}");
    assert!(!stale.exists(), "the dead writer's file is removed");
    assert!(live.exists(), "a live writer's file is left alone");
    assert!(users.exists(), "a file that is not lase's is left alone");
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            format!(".job.ngc.lase-{}.tmp", std::process::id()),
            ".job.ngc.lase-notes.tmp".to_string(),
            "job.ngc".to_string()
        ]
    );
}

/// `lase … | head`: the reader goes away; lase ends at once with SIGPIPE's status and says
/// nothing (no panic, no "Broken pipe" error), as `cat` would.
#[test]
fn a_closed_pipe_ends_lase_quietly() {
    for args in [
        vec!["plan", RECIPE],
        vec!["emit", "examples/texture_array.lase"],
        vec!["doc", "--markdown"],
        vec!["check", RECIPE],
    ] {
        // The reading end is closed before lase starts, so its first write meets a pipe with
        // no reader, whatever the scheduler does.
        let (reader, writer) = std::io::pipe().unwrap();
        drop(reader);
        let out = Command::new(lase_bin())
            .args(&args)
            .current_dir(common::root())
            .stdout(writer)
            .stderr(Stdio::piped())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(141), "{args:?}: {err}");
        assert!(err.is_empty(), "{args:?} said: {err}");
    }
}

/// `emit -o` says what it wrote in one line, as `plot -o` does (issue 18: a long job printed
/// nothing when done): the numbers are the file's own.
#[test]
fn emit_to_a_file_reports_the_lines_and_bytes_it_wrote() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("job.ngc");
    let p = out.to_string_lossy().into_owned();
    let (code, stdout, err) = common::lase(&["emit", RECIPE, "-o", &p]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    let expect = format!(
        "frame_marking.lase: wrote {p} ({} lines, {:.1} kB, linuxcnc)\n",
        text.lines().count(),
        text.len() as f64 / 1e3
    );
    assert_eq!(stdout, expect);
}
