//! Mesh streaming for displays: the daemon side encodes keyframes and deltas of each body's surface
//! in the layout of `proto/palpa_ipc.h` (positions as f32), and [`DisplayMesh`] is the client side
//! that rebuilds the mesh a display shows — exactly the daemon's f32 positions, bit for bit.
//!
//! A delta carries the vertices whose f32 position changed since the last message of that body, so
//! a display that joined on a keyframe and applied every delta since holds the same bits as the
//! daemon. Buffers are sized at start; encoding allocates nothing.

use crate::Vec3;
use crate::ipc::payload::{MESH_DELTA, MESH_KEYFRAME, MeshHeaderV1};

/// Bytes per vertex in a keyframe.
pub const KEYFRAME_VERTEX_BYTES: usize = 12;
/// Bytes per triangle in a keyframe.
pub const KEYFRAME_TRIANGLE_BYTES: usize = 12;
/// Bytes per changed vertex in a delta.
pub const DELTA_ENTRY_BYTES: usize = 16;

/// Largest slice a body's messages need: a keyframe (a delta is never larger).
pub fn max_message_bytes(vertices: usize, triangles: usize) -> usize {
    (vertices * KEYFRAME_VERTEX_BYTES + triangles * KEYFRAME_TRIANGLE_BYTES)
        .max(vertices * DELTA_ENTRY_BYTES)
}

fn to_f32(p: &Vec3) -> [f32; 3] {
    [p.x as f32, p.y as f32, p.z as f32]
}

fn put_f32(out: &mut [u8], at: usize, v: f32) {
    out[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn put_u32(out: &mut [u8], at: usize, v: u32) {
    out[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

/// The daemon side of one body's stream: what the displays were last sent.
#[derive(Clone, Debug)]
pub struct MeshEncoder {
    body: u32,
    sent: Vec<[f32; 3]>,
    sent_tick: u64,
    sent_topology: u64,
}

impl MeshEncoder {
    /// An encoder for body `body` with `vertices` vertices.
    pub fn new(body: u32, vertices: usize) -> Self {
        Self::with_capacity(body, vertices, vertices)
    }

    /// An encoder for body `body` with `vertices` vertices now and room for `capacity` (a body that
    /// subdivides), so that a keyframe of the grown mesh allocates nothing.
    pub fn with_capacity(body: u32, vertices: usize, capacity: usize) -> Self {
        let mut sent = Vec::with_capacity(capacity.max(vertices));
        sent.resize(vertices, [0.0; 3]);
        Self {
            body,
            sent,
            sent_tick: 0,
            sent_topology: 0,
        }
    }

    /// Whether the next message must be a keyframe: the mesh no longer has the vertices and
    /// triangles last sent (`topology` is the body's topology version).
    pub fn needs_keyframe(&self, vertices: usize, topology: u64) -> bool {
        vertices != self.sent.len() || topology != self.sent_topology
    }

    /// Writes a keyframe of `positions` and `triangles` at `tick` into `out`; returns its header.
    /// `out` must hold [`max_message_bytes`].
    pub fn keyframe(
        &mut self,
        tick: u64,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        out: &mut [u8],
    ) -> MeshHeaderV1 {
        let mut at = 0;
        self.sent.resize(positions.len(), [0.0; 3]);
        for (p, sent) in positions.iter().zip(self.sent.iter_mut()) {
            *sent = to_f32(p);
            for v in *sent {
                put_f32(out, at, v);
                at += 4;
            }
        }
        for t in triangles {
            for &v in t {
                put_u32(out, at, v);
                at += 4;
            }
        }
        self.sent_tick = tick;
        MeshHeaderV1 {
            kind: MESH_KEYFRAME,
            body: self.body,
            tick,
            base_tick: tick,
            vertex_count: positions.len() as u32,
            triangle_count: triangles.len() as u32,
            changed_count: 0,
            payload_bytes: at as u32,
        }
    }

    /// Writes the vertices whose f32 position changed since the last message into `out`; returns its
    /// header (with `changed_count` possibly 0).
    pub fn delta(&mut self, tick: u64, positions: &[Vec3], out: &mut [u8]) -> MeshHeaderV1 {
        let mut at = 0;
        let mut changed = 0;
        for (i, (p, sent)) in positions.iter().zip(self.sent.iter_mut()).enumerate() {
            let now = to_f32(p);
            if now.map(f32::to_bits) != sent.map(f32::to_bits) {
                *sent = now;
                put_u32(out, at, i as u32);
                for (k, v) in now.into_iter().enumerate() {
                    put_f32(out, at + 4 + 4 * k, v);
                }
                at += DELTA_ENTRY_BYTES;
                changed += 1;
            }
        }
        let base_tick = self.sent_tick;
        self.sent_tick = tick;
        MeshHeaderV1 {
            kind: MESH_DELTA,
            body: self.body,
            tick,
            base_tick,
            vertex_count: positions.len() as u32,
            triangle_count: 0,
            changed_count: changed,
            payload_bytes: at as u32,
        }
    }
}

/// Why a mesh message cannot be applied. A refused message leaves the mesh held as it was (a
/// [`MeshStreamError::Gap`] also marks it stale until the next keyframe).
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum MeshStreamError {
    /// A delta arrived before any keyframe.
    #[error("a delta arrived before a keyframe")]
    NoKeyframe,
    /// A delta does not apply to the state held (a message was missed): wait for a keyframe.
    #[error("delta for tick {base_tick} but the display holds tick {held}: wait for a keyframe")]
    Gap {
        /// The delta's base.
        base_tick: u64,
        /// What the display holds.
        held: u64,
    },
    /// The header's counts and the payload size disagree.
    #[error(
        "malformed mesh {kind}: its counts need {expected} payload bytes, the header says {declared} \
         and the slice holds {available}"
    )]
    Size {
        /// "keyframe" or "delta".
        kind: &'static str,
        /// Bytes the counts need.
        expected: u64,
        /// `payload_bytes` of the header.
        declared: u32,
        /// Bytes of the slice.
        available: usize,
    },
    /// A triangle corner or a delta entry names a vertex the mesh does not have.
    #[error(
        "malformed mesh {kind}: entry {entry} refers to vertex {vertex}, but the mesh has {vertices} vertices"
    )]
    VertexIndex {
        /// "keyframe" or "delta".
        kind: &'static str,
        /// Triangle (keyframe) or changed entry (delta), 0-based.
        entry: u32,
        /// The vertex it names.
        vertex: u32,
        /// Vertices of the mesh.
        vertices: u32,
    },
    /// A delta for a mesh of another size than the one held.
    #[error("malformed mesh delta: for {declared} vertices, but the display holds {held}")]
    VertexCount {
        /// The delta's `vertex_count`.
        declared: u32,
        /// Vertices held.
        held: usize,
    },
    /// Neither a keyframe nor a delta.
    #[error(
        "unknown mesh message kind {0} (expected {MESH_KEYFRAME}, keyframe, or {MESH_DELTA}, delta)"
    )]
    UnknownKind(u32),
}

/// The client side: the mesh of one body as a display holds it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DisplayMesh {
    /// Tick of the state held (valid once `ready`).
    pub tick: u64,
    /// Vertex positions (m, world, f32).
    pub positions: Vec<[f32; 3]>,
    /// Triangles.
    pub triangles: Vec<[u32; 3]>,
    /// A keyframe has been applied.
    pub ready: bool,
}

/// The little-endian u32 at `at`; callers have checked that `bytes` holds it.
fn get_u32(bytes: &[u8], at: usize) -> u32 {
    let mut word = [0u8; 4];
    word.copy_from_slice(&bytes[at..at + 4]);
    u32::from_le_bytes(word)
}

fn get_f32(bytes: &[u8], at: usize) -> f32 {
    f32::from_bits(get_u32(bytes, at))
}

/// Checks that `count` entries of `entry_bytes` fill the payload the header declares and that the
/// slice holds it; returns the size.
fn payload_size(
    kind: &'static str,
    count: u64,
    entry_bytes: u64,
    header: &MeshHeaderV1,
    bytes: &[u8],
) -> Result<usize, MeshStreamError> {
    // u32 counts times at most 24 bytes cannot overflow u64.
    let expected = count * entry_bytes;
    if expected != u64::from(header.payload_bytes) || expected > bytes.len() as u64 {
        return Err(MeshStreamError::Size {
            kind,
            expected,
            declared: header.payload_bytes,
            available: bytes.len(),
        });
    }
    Ok(expected as usize)
}

impl DisplayMesh {
    /// Applies one message. A display joining late ignores deltas (with [`MeshStreamError::NoKeyframe`])
    /// until a keyframe arrives; after a gap it waits for the next keyframe the same way. Any bytes
    /// are safe: a malformed message is refused with what is wrong and changes nothing, and nothing
    /// is allocated beyond what the slice holds.
    pub fn apply(&mut self, header: &MeshHeaderV1, bytes: &[u8]) -> Result<(), MeshStreamError> {
        let n = header.vertex_count;
        match header.kind {
            MESH_KEYFRAME => {
                let t = header.triangle_count;
                let per_vertex = KEYFRAME_VERTEX_BYTES as u64;
                let per_triangle = KEYFRAME_TRIANGLE_BYTES as u64;
                // Both counts are u32: the sum of their byte sizes fits u64 without overflow.
                let size = u64::from(n) * per_vertex + u64::from(t) * per_triangle;
                payload_size("keyframe", size, 1, header, bytes)?;
                let base = n as usize * KEYFRAME_VERTEX_BYTES;
                for triangle in 0..t {
                    for k in 0..3 {
                        let vertex = get_u32(bytes, base + 12 * triangle as usize + 4 * k);
                        if vertex >= n {
                            return Err(MeshStreamError::VertexIndex {
                                kind: "keyframe",
                                entry: triangle,
                                vertex,
                                vertices: n,
                            });
                        }
                    }
                }
                self.positions.clear();
                self.positions.extend(
                    (0..n as usize).map(|i| [0, 1, 2].map(|k| get_f32(bytes, 12 * i + 4 * k))),
                );
                self.triangles.clear();
                self.triangles.extend(
                    (0..t as usize)
                        .map(|i| [0, 1, 2].map(|k| get_u32(bytes, base + 12 * i + 4 * k))),
                );
                self.tick = header.tick;
                self.ready = true;
                Ok(())
            }
            MESH_DELTA => {
                if !self.ready {
                    return Err(MeshStreamError::NoKeyframe);
                }
                if header.base_tick != self.tick {
                    self.ready = false;
                    return Err(MeshStreamError::Gap {
                        base_tick: header.base_tick,
                        held: self.tick,
                    });
                }
                if n as usize != self.positions.len() {
                    return Err(MeshStreamError::VertexCount {
                        declared: n,
                        held: self.positions.len(),
                    });
                }
                let c = header.changed_count;
                payload_size(
                    "delta",
                    u64::from(c),
                    DELTA_ENTRY_BYTES as u64,
                    header,
                    bytes,
                )?;
                for entry in 0..c {
                    let vertex = get_u32(bytes, entry as usize * DELTA_ENTRY_BYTES);
                    if vertex >= n {
                        return Err(MeshStreamError::VertexIndex {
                            kind: "delta",
                            entry,
                            vertex,
                            vertices: n,
                        });
                    }
                }
                for e in 0..c as usize {
                    let at = e * DELTA_ENTRY_BYTES;
                    let i = get_u32(bytes, at) as usize;
                    self.positions[i] = [0, 1, 2].map(|k| get_f32(bytes, at + 4 + 4 * k));
                }
                self.tick = header.tick;
                Ok(())
            }
            kind => Err(MeshStreamError::UnknownKind(kind)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::default_scene;
    use crate::world::World;

    #[test]
    fn a_late_display_rebuilds_the_exact_mesh() {
        let mut world = World::from_scene(&default_scene());
        let body = &world.bodies[0];
        let bytes = max_message_bytes(body.node_count(), body.surface.triangles.len());
        let mut out = vec![0u8; bytes];
        let mut encoder = MeshEncoder::new(0, body.node_count());
        let mut display = DisplayMesh::default();
        let mut deltas = 0;
        for tick in 1..=600u64 {
            world.step();
            let b = &world.bodies[0];
            let header = if tick % 250 == 0 {
                encoder.keyframe(
                    tick,
                    &b.surface.position_in_world,
                    &b.surface.triangles,
                    &mut out,
                )
            } else {
                encoder.delta(tick, &b.surface.position_in_world, &mut out)
            };
            // The display joins at tick 100: deltas before its first keyframe are refused.
            if tick >= 100 {
                let applied = display.apply(&header, &out[..header.payload_bytes as usize]);
                if tick < 250 {
                    assert_eq!(applied, Err(MeshStreamError::NoKeyframe));
                } else {
                    applied.unwrap();
                    deltas += (header.kind == MESH_DELTA) as u32;
                }
            }
        }
        assert!(deltas > 300);
        let b = &world.bodies[0];
        assert_eq!(display.tick, 600);
        assert_eq!(display.triangles, b.surface.triangles);
        for (shown, exact) in display.positions.iter().zip(&b.surface.position_in_world) {
            assert_eq!(shown.map(f32::to_bits), to_f32(exact).map(f32::to_bits));
        }
    }

    #[test]
    fn a_missed_delta_is_detected() {
        let positions = vec![Vec3::zeros(); 3];
        let triangles = vec![[0, 1, 2]];
        let mut out = vec![0u8; max_message_bytes(3, 1)];
        let mut encoder = MeshEncoder::new(0, 3);
        let mut display = DisplayMesh::default();
        let h = encoder.keyframe(1, &positions, &triangles, &mut out);
        display.apply(&h, &out).unwrap();
        let moved = vec![Vec3::new(1.0, 0.0, 0.0); 3];
        let _lost = encoder.delta(2, &moved, &mut out);
        let h = encoder.delta(3, &positions, &mut out);
        assert_eq!(
            display.apply(&h, &out),
            Err(MeshStreamError::Gap {
                base_tick: 2,
                held: 1
            })
        );
        assert!(!display.ready);
    }
}

/// When mesh messages are due and what they hold: one message per body every `display_every` ticks,
/// a keyframe at start, every `keyframe_every` ticks and on request, deltas otherwise. Shared by the
/// daemon, headless recording and replay, so all three produce the same messages at the same ticks.
#[derive(Clone, Debug)]
pub struct MeshSchedule {
    display_every: u64,
    keyframe_every: u64,
    encoders: Vec<MeshEncoder>,
    scratch: Vec<u8>,
    keyframe_requested: bool,
    next_keyframe: u64,
}

impl MeshSchedule {
    /// A schedule for `world` at `display_rate_hz`, with keyframes every `keyframe_every_s` seconds.
    pub fn new(world: &crate::world::World, display_rate_hz: f64, keyframe_every_s: f64) -> Self {
        let dt = world.params.dt;
        // Bodies still to come (pieces of transections) get an encoder and room now; their first
        // message is a keyframe.
        let (spare_vertices, spare_triangles) = world.spare_mesh_capacity();
        let bytes = world
            .bodies
            .iter()
            .map(|b| {
                let (vertices, triangles) = b.mesh_capacity();
                max_message_bytes(vertices, triangles)
            })
            .chain(std::iter::once(max_message_bytes(
                spare_vertices,
                spare_triangles,
            )))
            .max()
            .unwrap_or(0)
            .max(1);
        let mut encoders: Vec<MeshEncoder> = world
            .bodies
            .iter()
            .enumerate()
            .map(|(i, b)| MeshEncoder::with_capacity(i as u32, b.node_count(), b.mesh_capacity().0))
            .collect();
        for i in world.bodies.len()..world.body_capacity() {
            let mut spare = MeshEncoder::with_capacity(i as u32, 0, spare_vertices);
            spare.sent_topology = u64::MAX;
            encoders.push(spare);
        }
        Self {
            display_every: ((1.0 / (display_rate_hz.max(1e-3) * dt)).round() as u64).max(1),
            keyframe_every: ((keyframe_every_s / dt).round() as u64).max(1),
            encoders,
            scratch: vec![0; bytes],
            keyframe_requested: true,
            next_keyframe: 0,
        }
    }

    /// Ticks between two mesh messages of a body (keyframes may come in between).
    pub fn display_every(&self) -> u64 {
        self.display_every
    }

    /// Largest message in bytes.
    pub fn max_message_bytes(&self) -> usize {
        self.scratch.len()
    }

    /// Asks for a keyframe at the next opportunity.
    pub fn request_keyframe(&mut self) {
        self.keyframe_requested = true;
    }

    /// Starts again (after a world reset): new encoders, a keyframe next.
    pub fn reset(&mut self, world: &crate::world::World) {
        for (e, b) in self.encoders.iter_mut().zip(&world.bodies) {
            *e = MeshEncoder::with_capacity(e.body, b.node_count(), b.mesh_capacity().0);
        }
        for e in self.encoders.iter_mut().skip(world.bodies.len()) {
            e.sent.clear();
            e.sent_topology = u64::MAX;
        }
        self.keyframe_requested = true;
    }

    /// If messages are due at the world's current tick, encodes one per body and hands each to
    /// `emit`. Allocates nothing.
    pub fn produce<E>(
        &mut self,
        world: &crate::world::World,
        mut emit: impl FnMut(&MeshHeaderV1, &[u8]) -> Result<(), E>,
    ) -> Result<(), E> {
        let tick = world.tick;
        let keyframe_due = self.keyframe_requested || tick >= self.next_keyframe;
        if tick % self.display_every != 0 && !keyframe_due {
            return Ok(());
        }
        let keyframe = keyframe_due;
        if keyframe {
            self.next_keyframe = tick.saturating_add(self.keyframe_every);
        }
        for (encoder, body) in self.encoders.iter_mut().zip(&world.bodies) {
            let s = &body.surface;
            let header = if keyframe
                || encoder.needs_keyframe(s.position_in_world.len(), body.topology_version)
            {
                encoder.sent_topology = body.topology_version;
                encoder.keyframe(tick, &s.position_in_world, &s.triangles, &mut self.scratch)
            } else {
                encoder.delta(tick, &s.position_in_world, &mut self.scratch)
            };
            emit(&header, &self.scratch[..header.payload_bytes as usize])?;
        }
        self.keyframe_requested = false;
        Ok(())
    }
}
