//! Ctrl-C as a request to finish: `trend` then ends its recording as at the end of
//! `--duration` (the CSV complete, the subscription stopped, the plot drawn). A second
//! Ctrl-C while it finishes ends the process at once (exit 130, as the shell's).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use signal_hook::consts::SIGINT;

use crate::fail::{Fail, Result};

/// Set by the first SIGINT.
#[derive(Clone)]
pub struct Interrupted(Arc<AtomicBool>);

impl Interrupted {
    pub fn is_set(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// Installs the handlers (once per command).
pub fn on_ctrl_c() -> Result<Interrupted> {
    let flag = Arc::new(AtomicBool::new(false));
    // The order matters: the shutdown hook checks the flag before the second hook sets it.
    signal_hook::flag::register_conditional_shutdown(SIGINT, 130, Arc::clone(&flag))
        .and_then(|_| signal_hook::flag::register(SIGINT, Arc::clone(&flag)))
        .map_err(|e| Fail::Usage(anyhow::anyhow!("cannot handle Ctrl-C: {e}")))?;
    Ok(Interrupted(flag))
}
