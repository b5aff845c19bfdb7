//! x10-devices: placeholder, filled by its issue.
