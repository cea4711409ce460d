//! The solver's working set: every body's rest data and state concatenated into one vertex
//! range, in the simulation's precision.

use std::ops::Range;

use nalgebra::Vector3;

use crate::error::Result;
use crate::membrane::{GatheredResponse, Membrane, PackedRest, RestData};
use crate::mesh::Neighborhood;
use crate::real::Real;
use crate::symmetric::SymmetricMatrix3;

use super::jacobi::LocalSystem;

/// Concatenated bodies.
pub(crate) struct System<T: Real> {
    /// Identity of each body, to detect a changed body list.
    pub ids: Vec<u64>,
    /// Vertex range of each body.
    pub ranges: Vec<Range<usize>>,
    pub nb: Neighborhood,
    /// Per-vertex constants, and (without `packed`) frames and bonds.
    pub rest: RestData<T>,
    /// The rest data in SIMD packs for the host kernel, when built for it (then `rest.frames`
    /// and `rest.bonds` are empty).
    pub packed: Option<PackedRest<T::Pack>>,
    /// Positions at the start of the step, y_t.
    pub y_start: Vec<Vector3<T>>,
    pub velocity: Vec<Vector3<T>>,
    /// Inertial target y* (pinned vertices: their target).
    pub y_star: Vec<Vector3<T>>,
    /// Current iterate and the next one.
    pub y: Vec<Vector3<T>>,
    pub y_next: Vec<Vector3<T>>,
    /// The iterate before `y`, kept only while Chebyshev acceleration needs it (else empty).
    pub y_prev: Vec<Vector3<T>>,
    pub pinned: Vec<bool>,
    /// Scratch of the global step: per-bond gradients and per-vertex responses.
    pub bond_grad: Vec<Vector3<T>>,
    pub response: Vec<GatheredResponse<T>>,
    /// Partial sums of the energy reductions (reused).
    pub energy_chunks: Vec<f64>,
    /// Per-vertex linear systems and moves, kept only when inner sweeps or the descent method
    /// need them (else empty).
    pub locals: Vec<LocalSystem<T>>,
    pub delta: Vec<Vector3<T>>,
    pub delta_next: Vec<Vector3<T>>,
}

impl<T: Real> System<T> {
    /// Concatenates the bodies' rest data, computed here a vertex (or a pack) at a time
    /// (state is loaded by [`System::load`]).
    ///
    /// With `packed`, frames and bonds go into SIMD packs for the host kernel (the CPU solver)
    /// and `rest` keeps only the per-vertex constants; without, everything goes into `rest`
    /// (for upload to a GPU).
    pub fn build(bodies: &[&mut Membrane], packed: bool) -> Result<Self> {
        let mut ids = Vec::with_capacity(bodies.len());
        let mut ranges = Vec::with_capacity(bodies.len());
        let vertices: usize = bodies.iter().map(|b| b.num_vertices()).sum();
        let bonds: usize = bodies.iter().map(|b| b.neighborhood().indices.len()).sum();
        let mut nb = Neighborhood {
            offsets: Vec::with_capacity(vertices + 1),
            indices: Vec::with_capacity(bonds),
            reverse: Vec::with_capacity(bonds),
        };
        nb.offsets.push(0);
        let mut rest = RestData::empty();
        rest.reserve(vertices, if packed { 0 } else { bonds }, !packed);
        let mut packs = packed.then(PackedRest::empty);
        let mut start = 0;
        for body in bodies {
            let n = body.num_vertices();
            ids.push(body.id());
            ranges.push(start..start + n);
            let (vertex_base, bond_base) = (start as u32, nb.indices.len() as u32);
            let own = body.neighborhood();
            nb.offsets
                .extend(own.offsets[1..].iter().map(|o| o + bond_base));
            nb.indices
                .extend(own.indices.iter().map(|j| j + vertex_base));
            nb.reverse.extend(own.reverse.iter().map(|b| b + bond_base));
            let source = body.rest_source()?;
            match &mut packs {
                Some(packs) => packs.add_body(own, &source, &mut |v| rest.push(v, false))?,
                None => rest.extend_from(&source, true)?,
            }
            start += n;
        }
        let zeros = vec![Vector3::zeros(); start];
        let zero_response = GatheredResponse::new(SymmetricMatrix3::zeros(), T::zero());
        Ok(Self {
            ids,
            ranges,
            bond_grad: vec![Vector3::zeros(); nb.indices.len()],
            nb,
            rest,
            packed: packs,
            y_start: zeros.clone(),
            velocity: zeros.clone(),
            y_star: zeros.clone(),
            y: zeros.clone(),
            y_next: zeros,
            y_prev: Vec::new(),
            pinned: vec![false; start],
            response: vec![zero_response; start],
            energy_chunks: Vec::new(),
            locals: Vec::new(),
            delta: Vec::new(),
            delta_next: Vec::new(),
        })
    }

    /// True when the system was built from exactly these bodies.
    pub fn matches(&self, bodies: &[&mut Membrane]) -> bool {
        self.ids.len() == bodies.len() && self.ids.iter().zip(bodies).all(|(id, b)| *id == b.id())
    }

    /// Copies the bodies' positions, velocities and pins in; pinned vertices get their target
    /// as inertial target.
    pub fn load(&mut self, bodies: &[&mut Membrane]) {
        for (body, range) in bodies.iter().zip(&self.ranges) {
            let base = range.start;
            for (k, (x, v)) in body.positions().iter().zip(body.velocities()).enumerate() {
                self.y_start[base + k] = x.map(T::of);
                self.velocity[base + k] = v.map(T::of);
            }
        }
        self.load_pins(bodies);
    }

    /// Copies the bodies' pins in: the flags, and their targets into `y_star`.
    pub fn load_pins(&mut self, bodies: &[&mut Membrane]) {
        self.pinned.fill(false);
        for (body, range) in bodies.iter().zip(&self.ranges) {
            for (&i, target) in body.pins() {
                self.pinned[range.start + i as usize] = true;
                self.y_star[range.start + i as usize] = target.map(T::of);
            }
        }
    }

    /// Copies the state back into the bodies (in f64).
    pub fn store(&self, bodies: &mut [&mut Membrane]) {
        for (body, range) in bodies.iter_mut().zip(&self.ranges) {
            let (x, v) = body.state_mut();
            for (k, i) in range.clone().enumerate() {
                x[k] = self.y_start[i].map(|c| c.to_f64());
                v[k] = self.velocity[i].map(|c| c.to_f64());
            }
        }
    }

    /// The body and local vertex index of a global vertex.
    pub fn locate(&self, vertex: usize) -> (usize, usize) {
        let body = self
            .ranges
            .iter()
            .position(|r| r.contains(&vertex))
            .unwrap_or(0);
        (body, vertex - self.ranges.get(body).map_or(0, |r| r.start))
    }
}
