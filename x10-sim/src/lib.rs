//! x10-sim: placeholder, filled by its issue.
