//! Media (to be written).
