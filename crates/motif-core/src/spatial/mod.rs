//! Spatial queries: a 3-D kd-tree for point neighbourhoods ([`KdTree`]) and blocked brute-force
//! nearest neighbours for high-dimensional descriptors ([`descriptor_nn`]).

mod descriptor_nn;
mod kdtree;

pub use descriptor_nn::{DescriptorMatch, DescriptorNnOptions, descriptor_knn, descriptor_nn};
pub use kdtree::{KdTree, Neighbour};
