//! x10-tests: placeholder, filled by its issue.
