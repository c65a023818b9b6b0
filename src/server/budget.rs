//! How many bytes of refused uploads the service reads, per second, to give their clients a
//! clean 503.
//!
//! A refused body that is not read costs nothing, but a client still sending it when the
//! connection closes may see a broken pipe instead of the 503: hyper-based clients (reqwest)
//! finish writing the body before they look at the answer, and report the failed write. Reading
//! the body avoids that, at the price of reading it, which at four times the capacity left a
//! fifth of the capacity for accepted requests. So refused bodies are read while this budget
//! lasts (a burst of refusals is answered cleanly), and left unread beyond it (a flood costs
//! next to nothing).

use std::sync::Mutex;
use std::time::Instant;

pub struct DrainBudget {
    /// Bytes available, and when they were counted.
    state: Mutex<(f64, Instant)>,
    bytes_per_second: f64,
    burst: f64,
}

impl DrainBudget {
    pub fn new(bytes_per_second: f64, burst: f64) -> Self {
        DrainBudget {
            state: Mutex::new((burst, Instant::now())),
            bytes_per_second,
            burst,
        }
    }

    /// Takes `bytes` from the budget, if it holds that many.
    pub fn take(&self, bytes: u64) -> bool {
        let Ok(mut state) = self.state.lock() else {
            return false;
        };
        let now = Instant::now();
        let (available, counted) = *state;
        let refilled = (available
            + now.duration_since(counted).as_secs_f64() * self.bytes_per_second)
            .min(self.burst);
        let wanted = bytes as f64;
        if wanted <= refilled {
            *state = (refilled - wanted, now);
            true
        } else {
            *state = (refilled, now);
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_burst_is_granted_then_the_rate() {
        let budget = DrainBudget::new(1000.0, 5000.0);
        assert!(budget.take(3000));
        assert!(budget.take(2000));
        assert!(!budget.take(1000), "the burst is spent");
        std::thread::sleep(std::time::Duration::from_millis(1100));
        assert!(budget.take(1000), "a second refilled it by the rate");
        assert!(!budget.take(1000));
    }
}
