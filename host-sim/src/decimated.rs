//! A sequence that stays small however long the run: decimated evenly as it grows, for
//! the paths the live channels and the live page draw.

/// Points in the order they came, at most `cap` kept: when full, every other kept point is
/// dropped and from then on only every other new one is kept (every fourth after the next
/// time, ...), so the kept points stay evenly spread; the newest point offered is held
/// apart, so the sequence always ends where the robot is.
#[derive(Clone, Debug)]
pub struct Decimated<T> {
    kept: Vec<T>,
    cap: usize,
    /// Keep one point in `stride`.
    stride: u64,
    /// Points offered since the last kept one.
    since_kept: u64,
    newest: Option<T>,
}

impl<T: Copy + PartialEq> Decimated<T> {
    /// An empty sequence that keeps at most `cap` points (plus the newest).
    pub fn new(cap: usize) -> Decimated<T> {
        Decimated {
            kept: Vec::new(),
            cap,
            stride: 1,
            since_kept: 0,
            newest: None,
        }
    }

    /// Adds the next point.
    pub fn push(&mut self, point: T) {
        self.newest = Some(point);
        self.since_kept += 1;
        if self.since_kept < self.stride {
            return;
        }
        self.since_kept = 0;
        if self.kept.len() >= self.cap {
            // Keep the even ones (the first among them), double the stride.
            let mut i = 0;
            self.kept.retain(|_| {
                i += 1;
                i % 2 == 1
            });
            self.stride = self.stride.saturating_mul(2);
        }
        self.kept.push(point);
    }

    /// The kept points, then the newest one if it was not kept: at most `cap` + 1.
    pub fn points(&self) -> impl Iterator<Item = &T> {
        let tail = match (self.kept.last(), &self.newest) {
            (Some(k), Some(n)) if k == n => None,
            (_, n) => n.as_ref(),
        };
        self.kept.iter().chain(tail)
    }

    /// The newest point, if any.
    pub fn newest(&self) -> Option<T> {
        self.newest
    }

    /// Whether nothing was pushed.
    pub fn is_empty(&self) -> bool {
        self.newest.is_none()
    }

    /// Forgets every point.
    pub fn clear(&mut self) {
        *self = Decimated::new(self.cap);
    }
}
