pub mod cumulus;
pub mod octree_tables;
