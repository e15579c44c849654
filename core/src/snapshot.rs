//! Snapshots: the whole world as bytes, to save, send to a late joiner, or
//! rewind to.
//!
//! Layout: the 8-byte magic `LSSNAP07`, then the world encoded with bincode
//! 2's standard configuration (little-endian, variable-length integers).
//! Every field that influences later steps is included, so a restored world
//! steps exactly as the original would have: tested by restoring at tick k
//! and comparing every later hash with the uninterrupted run.

use thiserror::Error;

use crate::world::World;

/// The first bytes of every snapshot; the last two digits are the format
/// version.
pub const SNAPSHOT_MAGIC: [u8; 8] = *b"LSSNAP07";

/// The largest snapshot [`restore`](World::restore) accepts (1 GiB): a
/// corrupt length field must not make it allocate without bound.
pub const MAX_SNAPSHOT_BYTES: usize = 1 << 30;

/// Why a snapshot could not be restored.
#[derive(Debug, Error, Clone, PartialEq, Eq)]
pub enum SnapshotError {
    /// The bytes do not start with [`SNAPSHOT_MAGIC`]: not a snapshot, or
    /// one from an incompatible version.
    #[error("not a lockstep snapshot (or an incompatible version): bad magic bytes")]
    BadMagic,
    /// The payload could not be decoded.
    #[error("corrupt snapshot: {0}")]
    Corrupt(String),
    /// Bytes were left over after the world.
    #[error("corrupt snapshot: {0} trailing bytes")]
    TrailingBytes(usize),
    /// The decoded world breaks an invariant.
    #[error("invalid snapshot: {0}")]
    Invalid(String),
}

impl World {
    /// The world as bytes (see the module docs for the layout).
    ///
    /// A world restored from a snapshot continues exactly as the original:
    ///
    /// ```
    /// use lockstep_core::{BodyDesc, ColliderDesc, Vec3, World, WorldConfig, scalar};
    ///
    /// let mut world = World::new(WorldConfig::default())?;
    /// let cube = world.create_body(&BodyDesc::dynamic().angular_velocity(Vec3::from_ints(1, 2, 3)))?;
    /// world.add_collider(cube, ColliderDesc::cuboid(scalar!(0.5), scalar!(0.25), scalar!(1)))?;
    /// for _ in 0..30 {
    ///     world.step();
    /// }
    ///
    /// let bytes = world.snapshot();
    /// let mut copy = World::restore(&bytes)?;
    /// assert_eq!(copy.state_hash(), world.state_hash());
    /// for _ in 0..30 {
    ///     world.step();
    ///     copy.step();
    /// }
    /// assert_eq!(copy.tick(), 60);
    /// assert_eq!(copy.state_hash(), world.state_hash()); // bit-identical
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn snapshot(&self) -> Vec<u8> {
        let mut out = SNAPSHOT_MAGIC.to_vec();
        // Encoding into a Vec cannot fail for these types.
        if let Ok(bytes) = bincode::serde::encode_to_vec(self, bincode::config::standard()) {
            out.extend_from_slice(&bytes);
        }
        out
    }

    /// A world from [`snapshot`](World::snapshot) bytes.
    ///
    /// # Errors
    /// [`SnapshotError`] for anything that is not an intact snapshot.
    pub fn restore(bytes: &[u8]) -> Result<World, SnapshotError> {
        let payload = bytes
            .strip_prefix(&SNAPSHOT_MAGIC[..])
            .ok_or(SnapshotError::BadMagic)?;
        let config = bincode::config::standard().with_limit::<MAX_SNAPSHOT_BYTES>();
        let (mut world, used): (World, usize) = bincode::serde::decode_from_slice(payload, config)
            .map_err(|e| SnapshotError::Corrupt(e.to_string()))?;
        if used != payload.len() {
            return Err(SnapshotError::TrailingBytes(payload.len() - used));
        }
        world
            .config()
            .validate()
            .map_err(|e| SnapshotError::Invalid(e.to_string()))?;
        world.check_invariants().map_err(SnapshotError::Invalid)?;
        world.rebuild_derived();
        Ok(world)
    }
}
