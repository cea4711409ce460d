//! The membrane family's working set: every membrane's rest data and state concatenated into
//! one vertex range, in the simulation's precision.

use nalgebra::Vector3;

use crate::error::Result;
use crate::membrane::{GatheredResponse, Membrane, PackedRest, RestData};
use crate::mesh::Neighborhood;
use crate::real::Real;
use crate::symmetric::SymmetricMatrix3;

use crate::solve::point_system::PointSystem;
use crate::solve::points::Points;

/// The membrane family's working set: its bodies' points, and their rest data and kernel
/// scratch concatenated in the same vertex order.
pub(crate) struct MembraneSystem<T: Real> {
    /// The vertices' state and iterates.
    pub points: Points<T>,
    pub nb: Neighborhood,
    /// Per-vertex constants, and (without `packed`) frames and bonds.
    pub rest: RestData<T>,
    /// The rest data in SIMD packs for the host kernel, when built for it (then `rest.frames`
    /// and `rest.bonds` are empty).
    pub packed: Option<PackedRest<T::Pack>>,
    /// Scratch of the global step: per-bond gradients and per-vertex responses.
    pub bond_grad: Vec<Vector3<T>>,
    pub response: Vec<GatheredResponse<T>>,
    /// Per-vertex linear systems and moves, kept only when inner sweeps or the descent method
    /// need them (else empty).
    pub point_systems: Vec<PointSystem<T>>,
    pub delta: Vec<Vector3<T>>,
    pub delta_next: Vec<Vector3<T>>,
    /// Per vertex, the Jacobi block `D_k = m_k I + h^2 (n_k C_k + sum_j C_j)` (kg) of eq. 25
    /// that the last Jacobi move assembled, for the proximal metric of the contact local step
    /// that follows it ([`crate::contact::ProximalMetric::Jacobi`]), which would otherwise
    /// gather every vertex's responses again. Kept only once the local step asks for it (sized
    /// to the vertices; else empty); `blocks_fresh` says whether they are those of the current
    /// responses (no evaluation since the move).
    pub blocks: Vec<SymmetricMatrix3<T>>,
    pub blocks_fresh: bool,
}

impl<T: Real> MembraneSystem<T> {
    /// Concatenates the bodies' rest data, computed here a vertex (or a pack) at a time
    /// (state is loaded by [`Points::load`]).
    ///
    /// With `packed`, frames and bonds go into SIMD packs for the host kernel (the CPU solver)
    /// and `rest` keeps only the per-vertex constants; without, everything goes into `rest`
    /// (for upload to a GPU).
    pub fn build(bodies: &[&mut Membrane], packed: bool) -> Result<Self> {
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
        let zero_response = GatheredResponse::new(SymmetricMatrix3::zeros(), T::zero());
        let mass = rest.vertices.iter().map(|v| v.mass).collect();
        let margin = rest.vertices.iter().map(|v| v.half_thickness).collect();
        Ok(Self {
            points: Points::new(bodies, mass, margin),
            bond_grad: vec![Vector3::zeros(); nb.indices.len()],
            nb,
            rest,
            packed: packs,
            response: vec![zero_response; start],
            point_systems: Vec::new(),
            delta: Vec::new(),
            delta_next: Vec::new(),
            blocks: Vec::new(),
            blocks_fresh: false,
        })
    }
}
