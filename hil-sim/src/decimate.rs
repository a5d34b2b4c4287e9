//! Samples kept for the plot of a run of any length in bounded memory (issue 20): at most
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
