//! Per-cell majorant structure (to be written).
