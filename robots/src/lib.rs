//! x10-robots: placeholder, filled by its issue.
