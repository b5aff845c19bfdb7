//! firmware-db: placeholder, filled by its issue.
