//! The findings a model reports to the SoC ([`super::Peripheral::take_reports`]), each
//! once: a driver polling in a loop would otherwise flood the log.

use crate::time::Cycles;

/// Misuse and unsupported-feature reports of a model, for the SoC to print by name. Each kind
/// is reported once (a driver polling in a loop would otherwise flood the log).
#[derive(Debug, Clone, Default)]
pub struct Reports {
    name: &'static str,
    seen: Vec<&'static str>,
    pending: Vec<String>,
}

impl Reports {
    pub fn new(name: &'static str) -> Self {
        Reports {
            name,
            seen: Vec::new(),
            pending: Vec::new(),
        }
    }

    /// Records `detail` under `kind` unless that kind was already reported.
    pub fn once(&mut self, now: Cycles, kind: &'static str, detail: impl FnOnce() -> String) {
        if self.seen.contains(&kind) {
            return;
        }
        self.seen.push(kind);
        if self.pending.len() < 256 {
            self.pending
                .push(format!("{} @{}: {}", self.name, now, detail()));
        }
    }

    /// The reports since the last call.
    pub fn take(&mut self) -> Vec<String> {
        std::mem::take(&mut self.pending)
    }
}

/// Reports keyed by their whole text: each distinct message once, for models whose findings
/// carry the values that make them distinct (a channel, a register value).
#[derive(Debug, Clone, Default)]
pub struct DistinctReports {
    seen: Vec<String>,
    pending: Vec<String>,
}

impl DistinctReports {
    /// Records `msg` unless the same text was reported before.
    pub fn once(&mut self, msg: String) {
        if !self.seen.contains(&msg) {
            self.seen.push(msg.clone());
            self.pending.push(msg);
        }
    }

    /// The reports since the last call.
    pub fn take(&mut self) -> Vec<String> {
        std::mem::take(&mut self.pending)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_kind_is_reported_once_with_its_first_detail() {
        let mut r = Reports::new("TIM2");
        r.once(5, "cms", || "first".into());
        r.once(9, "cms", || "second".into());
        assert_eq!(r.take(), ["TIM2 @5: first"]);
        r.once(12, "cms", || "third".into());
        assert!(r.take().is_empty());
    }

    #[test]
    fn each_distinct_message_is_reported_once() {
        let mut r = DistinctReports::default();
        r.once("a".into());
        r.once("b".into());
        r.once("a".into());
        assert_eq!(r.take(), ["a", "b"]);
        r.once("b".into());
        assert!(r.take().is_empty());
    }
}
