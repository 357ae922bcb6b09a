//! Online tuning of the builder (the thesis's section 8.3): a moving scene is rebuilt every
//! frame, and which builder gives the fastest frame depends on the scene, the motion, the
//! view and the machine. [`AutoBuilder`] measures instead of modelling: it lets each candidate
//! build a few moving frames, keeps the one whose frames were fastest (median; the default, the
//! first candidate, unless another beats it by more than [`MARGIN`]), and measures again only
//! when the frame time drifts well away from what the chosen builder gave (the scene or the
//! view changed enough).
//!
//! It is a policy over measured frame times alone, so it is tested with made-up times; the
//! [`crate::pipeline::FramePipeline`] feeds it its moving frames and switches builders when
//! it says so.

use phr_bvh::phr::PhrOptions;
use phr_bvh::Builder;

/// Moving frames each candidate is given while exploring.
pub const TRIAL_FRAMES: usize = 8;
/// Of those, the first ones are left out of its median: the switch itself (a first build, the
/// auxiliary tree made, caches refilled).
pub const WARMUP_FRAMES: usize = 2;
/// The chosen builder is measured again once the median of the last [`RECENT_FRAMES`] moving
/// frames exceeds its median by this factor.
pub const DRIFT: f64 = 1.25;
pub const RECENT_FRAMES: usize = 16;
/// The first candidate (the default builder) is kept unless another's median beats it by more
/// than this fraction: closer medians are within this machine's frame-to-frame noise, and
/// a switch would then follow the noise.
pub const MARGIN: f64 = 0.03;

/// What the tuner is doing.
#[derive(Clone, Debug, PartialEq)]
pub enum AutoState {
    /// Trying candidate `index`: `frames` of its moving frames measured so far.
    Exploring { index: usize, frames: usize },
    /// Using candidate `index`, whose frames took `median_ms`.
    Chosen { index: usize, median_ms: f64 },
}

/// The builder chooser (see the module documentation).
#[derive(Clone, Debug)]
pub struct AutoBuilder {
    pub candidates: Vec<Builder>,
    pub state: AutoState,
    /// The median frame time each candidate gave when last tried (`None`: not yet).
    pub medians: Vec<Option<f64>>,
    /// The current trial's frame times, or the chosen builder's recent ones.
    times: Vec<f64>,
    /// How many times the candidates were measured (1 after the first exploration).
    pub rounds: u32,
}

impl Default for AutoBuilder {
    /// The thesis's builders for dynamic scenes and the fastest SAH builder: the LBVH, PHR-Fast,
    /// PHR-HQ and binned SAH.
    fn default() -> Self {
        Self::new(vec![
            Builder::Phr(PhrOptions::FAST),
            Builder::Lbvh(Default::default()),
            Builder::Phr(PhrOptions::HQ),
            "binned-sah".parse().expect("a builder name"),
        ])
    }
}

impl AutoBuilder {
    /// Tries `candidates` in order (at least one).
    pub fn new(candidates: Vec<Builder>) -> Self {
        assert!(!candidates.is_empty(), "at least one candidate");
        let medians = vec![None; candidates.len()];
        Self { candidates, state: AutoState::Exploring { index: 0, frames: 0 }, medians, times: Vec::new(), rounds: 0 }
    }

    /// The builder to use now.
    pub fn current(&self) -> Builder {
        match self.state {
            AutoState::Exploring { index, .. } | AutoState::Chosen { index, .. } => self.candidates[index],
        }
    }

    /// Takes the time of a moving frame built by [`AutoBuilder::current`]; returns the builder
    /// to switch to, if it changes.
    pub fn record(&mut self, frame_ms: f64) -> Option<Builder> {
        let before = self.current();
        match self.state {
            AutoState::Exploring { index, frames } => {
                if frames >= WARMUP_FRAMES {
                    self.times.push(frame_ms);
                }
                if frames + 1 < TRIAL_FRAMES {
                    self.state = AutoState::Exploring { index, frames: frames + 1 };
                } else {
                    self.medians[index] = Some(median(&mut self.times));
                    self.times.clear();
                    self.state = match index + 1 < self.candidates.len() {
                        true => AutoState::Exploring { index: index + 1, frames: 0 },
                        false => self.choose(),
                    };
                }
            }
            AutoState::Chosen { median_ms, .. } => {
                self.times.push(frame_ms);
                if self.times.len() > RECENT_FRAMES {
                    self.times.remove(0);
                }
                if self.times.len() == RECENT_FRAMES && median(&mut self.times.clone()) > DRIFT * median_ms {
                    // The scene or the view changed enough: measure everything again.
                    self.times.clear();
                    self.state = AutoState::Exploring { index: 0, frames: 0 };
                }
            }
        }
        let after = self.current();
        (after != before).then_some(after)
    }

    /// The candidate with the fastest median, unless the first is within [`MARGIN`] of it.
    fn choose(&mut self) -> AutoState {
        self.rounds += 1;
        let (index, median_ms) = self
            .medians
            .iter()
            .enumerate()
            .filter_map(|(k, m)| Some((k, (*m)?)))
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .expect("every candidate measured");
        match self.medians[0] {
            Some(first) if first <= median_ms * (1.0 + MARGIN) => AutoState::Chosen { index: 0, median_ms: first },
            _ => AutoState::Chosen { index, median_ms },
        }
    }

    /// For people: what it does and what it found.
    pub fn describe(&self) -> String {
        match &self.state {
            AutoState::Exploring { index, frames } => format!(
                "auto: trying {} ({}/{}), {} frame{} in",
                self.candidates[*index],
                index + 1,
                self.candidates.len(),
                frames,
                if *frames == 1 { "" } else { "s" }
            ),
            AutoState::Chosen { index, median_ms } => {
                let scores: Vec<String> = (self.candidates.iter().zip(&self.medians))
                    .filter_map(|(b, m)| Some(format!("{b} {:.1}", (*m)?)))
                    .collect();
                let chosen = self.candidates[*index];
                format!("auto: {chosen} ({median_ms:.1} ms a moving frame, the fastest of {})", scores.join(", "))
            }
        }
    }
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    if v.is_empty() {
        f64::INFINITY
    } else {
        v[v.len() / 2]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn three() -> AutoBuilder {
        AutoBuilder::new(vec![
            Builder::Phr(PhrOptions::FAST),
            Builder::Lbvh(Default::default()),
            Builder::Phr(PhrOptions::HQ),
        ])
    }

    /// Feeds `frames` frames whose time is `time(builder)`; returns the switches.
    fn run(auto: &mut AutoBuilder, frames: usize, time: impl Fn(Builder, usize) -> f64) -> Vec<Builder> {
        (0..frames).filter_map(|k| auto.record(time(auto.current(), k))).collect()
    }

    /// Each candidate is tried for its frames in turn, then the fastest median is kept, and
    /// stays while its frames stay as fast.
    #[test]
    fn it_tries_each_then_keeps_the_fastest() {
        let mut auto = three();
        let times = |b: Builder, k: usize| {
            let base = match b {
                Builder::Lbvh(_) => 30.0,
                Builder::Phr(o) if o == PhrOptions::FAST => 40.0,
                _ => 50.0,
            };
            // Noise, and a slow first frame after each switch (left out of the median).
            base + (k % 3) as f64 + if k.is_multiple_of(TRIAL_FRAMES) { 100.0 } else { 0.0 }
        };
        let switches = run(&mut auto, 3 * TRIAL_FRAMES, times);
        assert_eq!(switches.len(), 3, "to LBVH, to PHR-HQ, back to LBVH: {switches:?}");
        assert!(matches!(auto.state, AutoState::Chosen { index: 1, .. }), "{:?}", auto.state);
        assert!(matches!(auto.current(), Builder::Lbvh(_)));
        assert_eq!(auto.rounds, 1);
        assert!(auto.medians.iter().all(Option::is_some));
        // Frames as fast as measured, and a few slow ones: no new exploration.
        let quiet = run(&mut auto, 200, |b, k| times(b, k % 5 + 1) + if k.is_multiple_of(10) { 80.0 } else { 0.0 });
        assert!(quiet.is_empty(), "{quiet:?}");
        assert_eq!(auto.rounds, 1);
        assert!(auto.describe().contains("the fastest of"), "{}", auto.describe());
    }

    /// A candidate barely faster than the first (within the noise) does not replace it.
    #[test]
    fn the_first_stays_unless_clearly_beaten() {
        let mut auto = three();
        run(&mut auto, 3 * TRIAL_FRAMES, |b, _| match b {
            Builder::Lbvh(_) => 99.0,
            _ => 100.0,
        });
        assert!(matches!(auto.state, AutoState::Chosen { index: 0, .. }), "{}", auto.describe());
        let mut auto = three();
        run(&mut auto, 3 * TRIAL_FRAMES, |b, _| match b {
            Builder::Lbvh(_) => 90.0,
            _ => 100.0,
        });
        assert!(matches!(auto.state, AutoState::Chosen { index: 1, .. }), "{}", auto.describe());
    }

    /// When the chosen builder's frames become much slower (the scene changed), every
    /// candidate is measured again and the new fastest kept.
    #[test]
    fn a_drift_measures_again() {
        let mut auto = three();
        run(&mut auto, 3 * TRIAL_FRAMES, |b, _| if matches!(b, Builder::Lbvh(_)) { 10.0 } else { 20.0 });
        assert!(matches!(auto.current(), Builder::Lbvh(_)));
        // Now the LBVH's frames take 40 ms, PHR-HQ's 15.
        let later = |b: Builder, _| match b {
            Builder::Lbvh(_) => 40.0,
            Builder::Phr(o) if o == PhrOptions::HQ => 15.0,
            _ => 25.0,
        };
        run(&mut auto, RECENT_FRAMES + 3 * TRIAL_FRAMES, later);
        assert_eq!(auto.rounds, 2);
        assert!(matches!(auto.current(), Builder::Phr(o) if o == PhrOptions::HQ), "{}", auto.describe());
    }
}
