//! firmware-mb: placeholder, filled by its issue.
