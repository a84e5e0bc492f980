//! Registration of Nimbus' codeless schema (`schemas/`) with openusd's schema registry.
//! STUB (to be implemented).
