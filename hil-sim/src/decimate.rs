//! Samples kept for the plot of a run of any length in bounded memory: at most
//! `cap` samples, evenly spaced. When the buffer is full every other sample is dropped and
//! from then on only every second (then fourth, ...) new one is kept. The CSV is written
//! from the full stream, so it keeps every sample.

/// Samples kept for a plot (see the module doc).
#[derive(Debug, Clone)]
pub struct Decimator<T> {
    cap: usize,
    /// Keep every `stride`-th sample of the stream.
    stride: u64,
    /// Samples offered so far.
    seen: u64,
    kept: Vec<T>,
}

/// A plot is 1400 pixels wide: 200 000 samples are 140 per pixel column, plenty for the
/// envelope of the phase currents, and about 40 MB.
pub const PLOT_SAMPLES: usize = 200_000;

impl<T: Clone> Decimator<T> {
    /// At most `cap` samples (rounded up to an even number, at least 2).
    pub fn new(cap: usize) -> Self {
        Decimator {
            cap: cap.max(2).next_multiple_of(2),
            stride: 1,
            seen: 0,
            kept: Vec::new(),
        }
    }

    pub fn push(&mut self, s: &T) {
        let i = self.seen;
        self.seen += 1;
        if !i.is_multiple_of(self.stride) {
            return;
        }
        if self.kept.len() >= self.cap {
            // The kept samples are those at multiples of `stride`: keep the even ones.
            let mut k = 0;
            self.kept.retain(|_| {
                k += 1;
                k % 2 == 1
            });
            self.stride *= 2;
            if !i.is_multiple_of(self.stride) {
                return;
            }
        }
        self.kept.push(s.clone());
    }

    /// Every how many samples of the stream one is kept now.
    pub fn stride(&self) -> u64 {
        self.stride
    }

    pub fn into_vec(self) -> Vec<T> {
        self.kept
    }
}

/// Which samples a run keeps in its report (`on_sample` sees every one either way).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum KeepSamples {
    /// None (a CSV-only or summary-only run).
    None,
    /// Every sample (tests and library users that analyse the record).
    All,
    /// For a plot: evenly decimated to at most [`PLOT_SAMPLES`] (bounded memory).
    ForPlot,
}

impl KeepSamples {
    /// What a command-line run keeps: samples for its plot, if it draws one.
    pub fn for_plot(plot: bool) -> Self {
        if plot {
            KeepSamples::ForPlot
        } else {
            KeepSamples::None
        }
    }
}

/// Collects samples as [`KeepSamples`] says.
#[derive(Debug, Clone)]
pub struct Kept<T> {
    keep: KeepSamples,
    all: Vec<T>,
    plot: Decimator<T>,
}

impl<T: Clone> Kept<T> {
    pub fn new(keep: KeepSamples) -> Self {
        Kept {
            keep,
            all: Vec::new(),
            plot: Decimator::new(PLOT_SAMPLES),
        }
    }

    pub fn push(&mut self, s: &T) {
        match self.keep {
            KeepSamples::None => {}
            KeepSamples::All => self.all.push(s.clone()),
            KeepSamples::ForPlot => self.plot.push(s),
        }
    }

    pub fn into_vec(self) -> Vec<T> {
        match self.keep {
            KeepSamples::ForPlot => self.plot.into_vec(),
            KeepSamples::None | KeepSamples::All => self.all,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn memory_stays_bounded_and_the_kept_samples_evenly_spaced() {
        let mut d = Decimator::new(1000);
        for i in 0..1_000_000u64 {
            d.push(&i);
        }
        let stride = d.stride();
        let kept = d.into_vec();
        assert!(kept.len() <= 1000 && kept.len() > 500, "{}", kept.len());
        assert_eq!(kept[0], 0);
        assert!(
            kept.windows(2).all(|w| w[1] - w[0] == stride),
            "stride {stride}"
        );
        // The whole run is covered, up to one stride before the end.
        assert!(*kept.last().unwrap() >= 1_000_000 - stride);
    }

    #[test]
    fn a_short_run_keeps_every_sample() {
        let mut d = Decimator::new(PLOT_SAMPLES);
        for i in 0..5000u32 {
            d.push(&i);
        }
        assert_eq!(d.into_vec(), (0..5000).collect::<Vec<_>>());
    }
}
