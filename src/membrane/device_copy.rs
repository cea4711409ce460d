//! A membrane's state left on a device by a step there: which device buffers hold it, after
//! which of their steps, and (until it has been read back) how to read it back.

use std::fmt;
use std::sync::Arc;

use nalgebra::Vector3;

use crate::error::Result;

/// Reads one body's positions (m) and velocities (m/s) back from a device, in f64.
pub type Fetch = Arc<dyn Fn() -> Result<(Vec<Vector3<f64>>, Vec<Vector3<f64>>)> + Send + Sync>;

/// The copy of a membrane's positions and velocities that device buffers hold.
#[derive(Clone)]
pub struct DeviceCopy {
    /// Identifies the device buffers (one working set of a GPU solver).
    pub owner: u64,
    /// Steps those buffers had taken when they last wrote this body.
    pub epoch: u64,
    /// Some while the membrane's own positions and velocities are older than the device's.
    pub(super) fetch: Option<Fetch>,
}

impl DeviceCopy {
    /// The state of step `epoch` of the buffers `owner`, not yet read back.
    pub fn pending(owner: u64, epoch: u64, fetch: Fetch) -> Self {
        Self {
            owner,
            epoch,
            fetch: Some(fetch),
        }
    }

    /// Whether the membrane's own copy is older than this one.
    pub fn is_pending(&self) -> bool {
        self.fetch.is_some()
    }
}

impl fmt::Debug for DeviceCopy {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("DeviceCopy")
            .field("owner", &self.owner)
            .field("epoch", &self.epoch)
            .field("pending", &self.is_pending())
            .finish()
    }
}
