//! The true world: segments a beam can hit and tags a camera can read (the `world`
//! crate's [`solid`](::world::solid), which the scenario's checks use too).

pub use ::world::solid::*;
