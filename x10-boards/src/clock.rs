//! The clock of every board image: [`x10_hal::time::EmbassyClock`], re-exported here.

pub use x10_hal::time::EmbassyClock;
