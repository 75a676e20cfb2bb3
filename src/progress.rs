//! Progress as two numbers, `(done, total)`, from computations that report by stage.
//!
//! `diagnose` and the output-error fit tell what they are doing in sentences, one per stage (the command
//! line shows them); a stage made of parts (the candidates of a round) says how many are done with [`part`].
//! [`StageCount`] turns that stream into counts, so that every long computation of the Python package calls
//! its callback the same way, `progress(done, total)`: a stage counts one, a stage of n parts counts n. The
//! stages still to come are not all known in advance (the rounds of a diagnosis depend on what each finds):
//! `total` starts at the stages the caller expects at least and grows as parts are announced; `done` never
//! decreases, stays below `total` while the work runs, and equals it in the last report ([`StageCount::finish`]).

use std::sync::Mutex;

/// The sentence for a stage of `total` parts of which `done` are done: "`stage` (`done` of `total` done)".
pub fn part(stage: &str, done: usize, total: usize) -> String {
    format!("{stage} ({done} of {total} done)")
}

/// The stage and the counts of a sentence written by [`part`], or None for a plain stage.
fn parse_part(sentence: &str) -> Option<(&str, usize, usize)> {
    let inner = sentence.strip_suffix(" done)")?;
    let (stage, counts) = inner.rsplit_once(" (")?;
    let (done, total) = counts.split_once(" of ")?;
    Some((stage, done.parse().ok()?, total.parse().ok()?))
}

/// The stage being run: its sentence (without the part counts) and its parts (done, total); a plain stage
/// is one part.
struct Current {
    stage: String,
    parts: (usize, usize),
}

struct State {
    /// Parts of the stages finished.
    finished: usize,
    /// Stages started.
    started: usize,
    current: Option<Current>,
}

/// Counts the stages of a computation that reports sentences (see the module's documentation).
pub struct StageCount {
    expected: usize,
    state: Mutex<State>,
}

impl StageCount {
    /// A count for a computation of at least `expected` stages.
    pub fn new(expected: usize) -> Self {
        Self {
            expected,
            state: Mutex::new(State {
                finished: 0,
                started: 0,
                current: None,
            }),
        }
    }

    /// The counts after the computation reported `sentence` (it may be called from any thread).
    pub fn stage(&self, sentence: &str) -> (usize, usize) {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let (stage, parts) = match parse_part(sentence) {
            Some((stage, done, total)) => (stage, (done, total.max(done))),
            None => (sentence, (0, 1)),
        };
        let same =
            parse_part(sentence).is_some() && s.current.as_ref().is_some_and(|c| c.stage == stage);
        if same {
            // Parts of the stage running: reports may arrive out of order from several threads.
            let c = s.current.as_mut().expect("the stage running");
            c.parts = (c.parts.0.max(parts.0), c.parts.1.max(parts.1));
        } else {
            if let Some(c) = s.current.take() {
                s.finished += c.parts.1;
            }
            s.started += 1;
            s.current = Some(Current {
                stage: stage.to_string(),
                parts,
            });
        }
        self.counts(&s)
    }

    /// The counts of the whole computation, finished: (total, total).
    pub fn finish(&self) -> (usize, usize) {
        let s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let total = s.finished + s.current.as_ref().map_or(0, |c| c.parts.1);
        (total, total)
    }

    fn counts(&self, s: &State) -> (usize, usize) {
        let (done, parts) = s.current.as_ref().map_or((0, 0), |c| c.parts);
        let done = s.finished + done;
        let to_come = self.expected.saturating_sub(s.started);
        // Not finished until `finish`: at least one more unit to go.
        let total = (s.finished + parts + to_come).max(done + 1);
        (done, total)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_part_sentence_reads_back() {
        let s = part("round 2: fitting the candidates", 3, 8);
        assert_eq!(s, "round 2: fitting the candidates (3 of 8 done)");
        assert_eq!(
            parse_part(&s),
            Some(("round 2: fitting the candidates", 3, 8))
        );
        assert_eq!(parse_part("fitting the linear model (na=2)"), None);
    }

    #[test]
    fn stages_and_parts_count_up_to_the_total() {
        let c = StageCount::new(3);
        assert_eq!(c.stage("choosing the initial state"), (0, 3));
        assert_eq!(c.stage("fitting the linear model"), (1, 3));
        assert_eq!(c.stage("fitting the backlash model"), (2, 3));
        // A round of 4 candidates: the total grows by what it announces.
        assert_eq!(c.stage(&part("round 1", 0, 4)), (3, 7));
        assert_eq!(c.stage(&part("round 1", 2, 4)), (5, 7));
        // Out of order from another thread: no step back.
        assert_eq!(c.stage(&part("round 1", 1, 4)), (5, 7));
        assert_eq!(c.stage(&part("round 1", 4, 4)), (7, 8));
        assert_eq!(c.finish(), (7, 7));
    }

    #[test]
    fn done_never_decreases_and_stays_below_the_total_while_running() {
        let c = StageCount::new(2);
        let mut last = 0;
        for s in [
            "a".to_string(),
            part("b", 0, 2),
            part("b", 1, 2),
            part("b", 2, 2),
            part("c", 0, 3),
            part("c", 3, 3),
            "d".into(),
        ] {
            let (done, total) = c.stage(&s);
            assert!(done >= last && done < total, "{s}: {done} of {total}");
            last = done;
        }
        assert_eq!(c.finish(), (1 + 2 + 3 + 1, 7));
    }
}
