//! Nothing lost, nothing repeated: the simulated controller drops the TCP connection at
//! random (seeded) points; `lase run --resume JOURNAL` continues each job, and in the end the
//! controller has executed every line that does something exactly once, in order, and the
//! executed trajectory is the plan.

mod link_support;

use lase_runtime::link::sim::{Faults, SimOptions, TimeScale};
use link_support::*;
use std::time::Duration;

/// A small deterministic generator (xorshift64*), so failures reproduce.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    fn range(&mut self, lo: u64, hi: u64) -> u64 {
        lo + self.next() % (hi - lo).max(1)
    }
}

/// Cycles of drop → resume, for the record.
const TRIALS: u64 = 20;

#[test]
fn twenty_random_disconnects_each_resume_to_the_full_job_exactly_once() {
    let dir = tempfile::tempdir().unwrap();
    let jobs = examples();
    let compiled: Vec<Compiled> = jobs.iter().map(|p| compile(p)).collect();
    let baselines: Vec<_> = compiled.iter().map(baseline).collect();
    // LINK_SEED and LINK_TRIALS run other or more trials locally (a soak, not for CI).
    let seed = std::env::var("LINK_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x0001_a5ed_15c0_u64);
    let trials = std::env::var("LINK_TRIALS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(TRIALS);
    let mut rng = Rng(seed | 1);
    let mut cycles = 0;
    let mut repeated_dwells = 0;
    for trial in 0..trials {
        let which = (trial as usize) % jobs.len();
        let (path, c) = (&jobs[which], &compiled[which]);
        let n = c.lines.len() as u64;
        // Lines 1–3 the controller receives are `$G`, `$I` and `$$`; drop somewhere in the
        // job.
        let first = rng.range(4, n);
        // Every third trial drops a second time, during the resumed stream (after `$$`,
        // `$G` and about seven re-approach lines).
        let mut drops = vec![first];
        if trial % 3 == 2 {
            drops.push(first + 9 + rng.range(2, 12));
        }
        let time_scale = if trial % 2 == 0 {
            TimeScale::Max
        } else {
            TimeScale::Factor(200.0)
        };
        let sim = sim_for(
            &c.job,
            SimOptions {
                time_scale,
                faults: Faults {
                    drop_after_lines: drops.clone(),
                    ..Faults::default()
                },
                ..SimOptions::default()
            },
        );
        let journal = dir.path().join(format!("trial{trial}.journal"));
        let (code, _out, err) = lase(&[
            "run",
            path.to_str().unwrap(),
            "--link",
            &url(&sim),
            "--journal",
            journal.to_str().unwrap(),
        ]);
        assert_eq!(
            code, 1,
            "trial {trial} (drops {drops:?}): the link drops: {err}{_out}"
        );
        assert!(err.contains("lase::link::lost"), "trial {trial}: {err}");
        // Said once, not "lost after …: the link to the controller was lost: …".
        assert_eq!(
            err.matches("link to the controller was lost").count(),
            1,
            "trial {trial}: {err}"
        );
        assert!(err.contains("--resume"), "trial {trial}: {err}");
        let mut resumes_run = 0;
        loop {
            let (code, out, err) = lase(&["run", "--resume", journal.to_str().unwrap()]);
            if std::env::var_os("LINK_DEBUG").is_some() {
                eprintln!("trial {trial} resume: {err}");
                eprintln!(
                    "{}",
                    std::fs::read_to_string(&journal)
                        .unwrap()
                        .lines()
                        .filter(|l| !l.starts_with("s ") && !l.starts_with("a "))
                        .collect::<Vec<_>>()
                        .join("; ")
                );
            }
            cycles += 1;
            resumes_run += 1;
            if code == 0 {
                assert!(out.contains("done"), "{out}");
                break;
            }
            assert!(
                err.contains("lase::link::lost") && resumes_run < 4,
                "trial {trial} (drops {drops:?}): resume failed: {err}"
            );
        }
        assert!(sim.wait_quiet(Duration::from_secs(10)));
        let rec = sim.stop();
        assert_eq!(rec.rx_overflows, 0, "{:?}", rec.overflow_log);
        let resumes = journal_resumes(&journal);
        assert_eq!(resumes.len(), resumes_run, "trial {trial}");
        // A dwell in flight when the link drops leaves no trace in the controller's state,
        // nor does a program end after it: the resume runs them again (the one thing that may
        // repeat; nothing moves and nothing changes).
        let mut got = effective(&rec, &resumes);
        let before = got.len();
        got = without_reruns(got);
        repeated_dwells += before - got.len();
        if std::env::var_os("LINK_DEBUG").is_some() {
            for l in &rec.lines {
                eprintln!("{} c{} {:?} {}", l.seq, l.connection, l.result, l.text);
            }
        }
        let want = &without_reruns(baselines[which].clone());
        let first_diff = got
            .iter()
            .zip(want.iter())
            .position(|(g, w)| g.1 != w.1)
            .unwrap_or(got.len().min(want.len()));
        assert!(
            got.len() == want.len() && first_diff == got.len(),
            "trial {trial} (drops {drops:?}, resumes {resumes:?}): {} effective lines, {} planned; first difference at {first_diff}:\n got  {:?}\n want {:?}",
            got.len(),
            want.len(),
            got.get(first_diff),
            want.get(first_diff)
        );
        assert_trajectory_matches(c, &rec, &job_line_seqs(c, &rec, &resumes));
        let j = lase_runtime::link::journal::read(&journal).unwrap();
        assert_eq!(j.end.as_deref(), Some("done"));
    }
    assert!(
        cycles >= TRIALS as usize,
        "{cycles} disconnect/resume cycles"
    );
    eprintln!("{cycles} disconnect/resume cycles, {repeated_dwells} dwells run twice");
}

#[test]
fn resume_refuses_a_changed_recipe_and_a_finished_job() {
    let dir = tempfile::tempdir().unwrap();
    let recipe = dir.path().join("job.lase");
    std::fs::copy(root().join("examples/frame_marking.lase"), &recipe).unwrap();
    let c = compile(&recipe);
    let sim = sim_for(
        &c.job,
        SimOptions {
            time_scale: TimeScale::Max,
            faults: Faults {
                drop_after_lines: vec![12],
                ..Faults::default()
            },
            ..SimOptions::default()
        },
    );
    let journal = dir.path().join("j");
    let (code, _, err) = lase(&[
        "run",
        recipe.to_str().unwrap(),
        "--link",
        &url(&sim),
        "--journal",
        journal.to_str().unwrap(),
    ]);
    assert_eq!(code, 1, "{err}");
    // A new run must not overwrite the unfinished journal.
    let (code, _, err) = lase(&[
        "run",
        recipe.to_str().unwrap(),
        "--link",
        &url(&sim),
        "--journal",
        journal.to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("unfinished job"), "{err}");
    // The recipe changed since: refused.
    let text = std::fs::read_to_string(&recipe).unwrap();
    std::fs::write(&recipe, text.replace("at 20 mm/s", "at 25 mm/s")).unwrap();
    let (code, _, err) = lase(&["run", "--resume", journal.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("lase::link::resume"), "{err}");
    std::fs::write(&recipe, text).unwrap();
    let (code, _, err) = lase(&["run", "--resume", journal.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = lase(&["run", "--resume", journal.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("nothing to resume"), "{err}");
    sim.stop();
}

/// Effective lines with re-runs of dwells and program ends taken out: after a line that
/// moves or changes state, a dwell or program end equal to one already seen since that line
/// is a re-run (see the resume's guards: these are the only lines it may send twice).
fn without_reruns(
    lines: Vec<(String, lase_runtime::link::sim::Effect)>,
) -> Vec<(String, lase_runtime::link::sim::Effect)> {
    let mut out = Vec::with_capacity(lines.len());
    let mut since_change: Vec<lase_runtime::link::sim::Effect> = Vec::new();
    for (text, e) in lines {
        let harmless = e.motion.is_none()
            && e.changes.is_empty()
            && (e.dwell_s.is_some() || e.flow == Some("end"));
        if !harmless {
            since_change.clear();
        } else if since_change.contains(&e) {
            continue;
        } else {
            since_change.push(e.clone());
        }
        out.push((text, e));
    }
    out
}

/// `lase run` with env `XDG_STATE_HOME=state` (and `HOME` elsewhere, so nothing of the user's
/// is touched), from the repository root.
fn lase_state(state: &std::path::Path, args: &[&str]) -> (i32, String, String) {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_lase"))
        .args(args)
        .current_dir(root())
        .env("NO_COLOR", "1")
        .env("XDG_STATE_HOME", state)
        .env("HOME", state.join("home"))
        .output()
        .expect("the lase binary runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

#[test]
fn without_journal_the_journal_goes_to_the_state_directory_and_resume_finds_it() {
    let dir = tempfile::tempdir().unwrap();
    let state = dir.path().join("state");
    // Two recipes with the same file name in different folders.
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    std::fs::create_dir_all(&a).unwrap();
    std::fs::create_dir_all(&b).unwrap();
    let (ra, rb) = (a.join("job.lase"), b.join("job.lase"));
    for r in [&ra, &rb] {
        std::fs::copy(root().join("examples/frame_marking.lase"), r).unwrap();
    }
    let c = compile(&ra);
    let dropping = || {
        sim_for(
            &c.job,
            SimOptions {
                time_scale: TimeScale::Max,
                faults: Faults {
                    drop_after_lines: vec![12],
                    ..Faults::default()
                },
                ..SimOptions::default()
            },
        )
    };
    let journals = state.join("lase/journals");
    let mut paths = Vec::new();
    let mut sims = Vec::new();
    for r in [&ra, &rb] {
        let sim = dropping();
        let (code, _, err) =
            lase_state(&state, &["run", r.to_str().unwrap(), "--link", &url(&sim)]);
        assert_eq!(code, 1, "{err}");
        // Nothing beside the recipe; the output says where the journal is.
        let beside: Vec<_> = std::fs::read_dir(r.parent().unwrap()).unwrap().collect();
        assert_eq!(beside.len(), 1, "only the recipe in its folder");
        let listed: Vec<_> = std::fs::read_dir(&journals)
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| !paths.contains(p))
            .collect();
        assert_eq!(listed.len(), 1, "one new journal per recipe: {listed:?}");
        let j = &listed[0];
        assert!(err.contains(&format!("journal {}", j.display())), "{err}");
        assert!(err.contains("--resume"), "{err}");
        paths.push(j.clone());
        sims.push(sim);
    }
    assert_ne!(paths[0], paths[1]);
    // `lase run FILE --resume` finds the recipe's own journal (which names the link) and
    // finishes the job on the controller that lost it.
    let (code, _, err) = lase_state(&state, &["run", rb.to_str().unwrap(), "--resume"]);
    assert_eq!(code, 0, "{err}");
    let done = lase_runtime::link::journal::read(&paths[1]).unwrap();
    assert_eq!(done.end.as_deref(), Some("done"));
    let open = lase_runtime::link::journal::read(&paths[0]).unwrap();
    assert_eq!(open.end, None, "the other recipe's journal is untouched");
    for sim in sims {
        sim.stop();
    }
    // No journal for a recipe that never ran: a clear refusal.
    let other = dir.path().join("never.lase");
    std::fs::copy(root().join("examples/frame_marking.lase"), &other).unwrap();
    let (code, _, err) = lase_state(&state, &["run", other.to_str().unwrap(), "--resume"]);
    assert_eq!(code, 1);
    assert!(err.contains("no journal of"), "{err}");
}
