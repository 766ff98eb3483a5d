//! The Lloyd iteration: seeding, flooding, fitting, teleportation. (Being written.)

use super::{Progress, ProxyMetric, SegmentError, SegmentOptions, Segmentation};
use crate::mesh::Mesh;

pub(super) fn run<M: ProxyMetric>(
    _mesh: &Mesh,
    _metric: &M,
    _options: &SegmentOptions,
    _progress: &mut dyn FnMut(Progress),
) -> Result<Segmentation<M::Proxy>, SegmentError> {
    todo!("being written")
}
