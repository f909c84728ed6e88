//! The loop the flow, IMU and depth tasks run: start the part, backing off while it fails;
//! read it at its rate until it is lost; start it again. (The camera only listens: its
//! link has no start-up to retry.)
//!
//! A part that stops answering (unplugged, browned out, a bus stuck by a glitch) comes back
//! by itself, and how often that happens shows in [`HEALTH`](crate::health::HEALTH): each
//! failed start-up and each bus error or timeout is counted in the part's own counters. The
//! part supplies one start-up attempt and one read ([`Supervised`]); the timings and the
//! counters are a [`Supervisor`].

use embassy_time::{Duration, Ticker, Timer};

use crate::health::Counter;

/// How one part is started, paced and given up on, and where its faults are counted.
pub struct Supervisor {
    /// Wait after the first failed start-up; doubled after each further failure.
    pub first_backoff: Duration,
    /// Longest wait between two start-up attempts.
    pub max_backoff: Duration,
    /// How reads are spaced.
    pub pace: Pace,
    /// Failed reads in a row after which the part is lost and started again.
    pub errors_before_restart: u32,
    /// Counts every failed start-up attempt.
    pub start_failures: &'static Counter,
    /// Counts every bus error or timeout, in start-up or reads.
    pub bus_errors: &'static Counter,
}

/// How reads are spaced.
pub enum Pace {
    /// One read per period on a fixed grid (a [`Ticker`]): a slow read does not shift the
    /// next. For parts sampled at their output data rate.
    Every(Duration),
    /// A pause of this long before each read ([`Timer::after`]). For polling a part that
    /// says when it has data, where a blocking read may overrun the period.
    // Only the depth sensor polls, and it is built only with its feature.
    #[cfg_attr(not(feature = "vl53l5cx"), allow(dead_code))]
    After(Duration),
}

/// Why one start-up attempt failed. The part has logged the details.
pub enum StartFailure {
    /// A bus error or a timeout: also counted in [`Supervisor::bus_errors`].
    Bus,
    /// Anything else (a wrong ID, a step the part refused, a driver that does not say).
    Other,
}

/// What one read came to.
pub enum Read {
    /// The part answered: the run of failures ends, whatever the data said.
    Answered,
    /// The part has nothing yet (no frame ready): neither an answer nor a failure.
    #[cfg_attr(not(feature = "vl53l5cx"), allow(dead_code))]
    NotReady,
    /// A bus error or a timeout: counted in [`Supervisor::bus_errors`], one more failure in a
    /// row.
    BusError,
    /// The part answered with something unusable that it counted itself: one more failure
    /// in a row, but not a bus error.
    Failed,
}

/// A part a [`Supervisor`] can start and read.
pub trait Supervised {
    /// One start-up attempt. Logs what failed; the supervisor counts it and waits.
    async fn try_start(&mut self) -> Result<(), StartFailure>;

    /// Start-up succeeded: logs that the part runs.
    fn started(&self);

    /// Reads are about to begin (after each start-up): resets any per-run state.
    fn reads_begin(&mut self) {}

    /// One read, and whatever the task does with its data.
    async fn read(&mut self) -> Read;

    /// The part was lost: logs it, before it is started again.
    fn lost(&self);
}

impl Supervisor {
    /// Starts the part and reads it until it is lost, over and over, for good.
    pub async fn run(&self, part: &mut impl Supervised) -> ! {
        loop {
            self.start(part).await;
            self.read_until_lost(part).await;
        }
    }

    /// Starts the part, retrying with a doubling back-off until it answers.
    pub async fn start(&self, part: &mut impl Supervised) {
        let mut backoff = self.first_backoff;
        loop {
            match part.try_start().await {
                Ok(()) => {
                    part.started();
                    return;
                }
                Err(StartFailure::Bus) => self.bus_errors.bump(),
                Err(StartFailure::Other) => {}
            }
            self.start_failures.bump();
            Timer::after(backoff).await;
            backoff = (backoff * 2).min(self.max_backoff);
        }
    }

    /// Reads the part at its pace until [`Supervisor::errors_before_restart`] reads in a row
    /// have failed.
    pub async fn read_until_lost(&self, part: &mut impl Supervised) {
        let mut pacer = Pacer::new(&self.pace);
        part.reads_begin();
        let mut failures_in_a_row = 0;
        while failures_in_a_row < self.errors_before_restart {
            pacer.wait().await;
            match part.read().await {
                Read::Answered => failures_in_a_row = 0,
                Read::NotReady => {}
                Read::BusError => {
                    self.bus_errors.bump();
                    failures_in_a_row += 1;
                }
                Read::Failed => failures_in_a_row += 1,
            }
        }
        part.lost();
    }
}

/// One run of reads' clock, made from a [`Pace`] as the run begins.
enum Pacer {
    Ticker(Ticker),
    Pause(Duration),
}

impl Pacer {
    fn new(pace: &Pace) -> Self {
        match *pace {
            Pace::Every(period) => Pacer::Ticker(Ticker::every(period)),
            Pace::After(pause) => Pacer::Pause(pause),
        }
    }

    /// Waits until the next read is due.
    async fn wait(&mut self) {
        match self {
            Pacer::Ticker(ticker) => ticker.next().await,
            Pacer::Pause(pause) => Timer::after(*pause).await,
        }
    }
}
