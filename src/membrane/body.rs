//! The membrane body: mesh, parameters and state (positions, velocities, pins). Its rest data
//! are not stored: they are computed from the rest mesh whenever needed ([`RestSource`]).

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};

use nalgebra::Vector3;

use crate::error::{check_param, invalid, Result};
use crate::material::Material;
use crate::mesh::{Neighborhood, TriangleMesh};
use crate::point_state::PointState;

use crate::parallel::for_each_vertex;
use crate::symmetric::SymmetricMatrix3;

use super::kernel::{bond_vectors, vertex_kernel, Deformation, Preconditioner, VertexResponse};
use super::rest::lumped_volumes;
use super::{DeviceCopy, RestSource};

/// Physical parameters of a membrane (SI units).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MembraneParams {
    /// Full physical thickness (m); the virtual bond is half of it (the paper's xi).
    pub thickness: f64,
    /// Mass density (kg/m^3).
    pub density: f64,
    /// Stretching material.
    pub material: Material,
    /// Bending rigidity D (N m): a cylindrical bend of curvature k stores `D k^2 / 2` per area.
    pub bending: f64,
    /// In-plane hourglass stiffness relative to the shear modulus (dimensionless).
    pub hourglass: f64,
    /// k of the k-ring neighbourhood.
    pub neighbors: usize,
}

impl MembraneParams {
    /// Default hourglass stiffness: enough to suppress the checkerboard modes of the 1-ring
    /// deformation gradient while leaving smooth deformation untouched.
    pub const DEFAULT_HOURGLASS: f64 = 0.5;

    /// Checks every parameter, naming the first bad one.
    pub fn validate(&self) -> Result<()> {
        check_param(
            "thickness",
            self.thickness,
            |v| v > 0.0,
            "a finite length > 0 m",
        )?;
        check_param(
            "density",
            self.density,
            |v| v > 0.0,
            "a finite density > 0 kg/m^3",
        )?;
        check_param(
            "bending",
            self.bending,
            |v| v >= 0.0,
            "a finite rigidity >= 0 N m",
        )?;
        check_param(
            "hourglass",
            self.hourglass,
            |v| v >= 0.0,
            "a finite number >= 0",
        )?;
        if self.neighbors < 1 {
            return Err(invalid!(
                "neighbors must be >= 1 (the k of the k-ring), got {}",
                self.neighbors
            ));
        }
        Ok(())
    }
}

/// Elastic energy of a membrane split by term (J).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct EnergyTerms {
    pub stretch: f64,
    pub bending: f64,
    pub hourglass: f64,
}

impl EnergyTerms {
    /// Sum of the terms (J).
    pub fn total(&self) -> f64 {
        self.stretch + self.bending + self.hourglass
    }
}

static NEXT_ID: AtomicU64 = AtomicU64::new(1);

/// A thin hyperelastic membrane. Not `Clone`: its `id` is unique.
#[derive(Debug)]
pub struct Membrane {
    id: u64,
    mesh: TriangleMesh,
    neighborhood: Neighborhood,
    params: MembraneParams,
    state: PointState,
    self_contact: bool,
    /// Coulomb friction coefficient against other membranes (dimensionless, >= 0).
    friction: f64,
    /// The copy of `positions` and `velocities` a GPU step left on its device, if any.
    device: Option<DeviceCopy>,
}

impl Membrane {
    /// Builds a membrane at rest (positions = rest positions, zero velocity, nothing pinned).
    /// Fails, naming the vertex, where the rest data cannot be computed (every vertex's are
    /// computed once here and dropped, so that later computations cannot fail).
    pub fn new(mesh: TriangleMesh, params: MembraneParams) -> Result<Self> {
        params.validate()?;
        let neighborhood = Neighborhood::k_ring(&mesh, params.neighbors)?;
        let source = RestSource::new(&mesh, &neighborhood, &params)?;
        for i in 0..source.len() {
            source.vertex(i)?;
        }
        drop(source);
        let state = PointState::at_rest(mesh.vertices().to_vec());
        Ok(Self {
            id: NEXT_ID.fetch_add(1, Ordering::Relaxed),
            mesh,
            neighborhood,
            params,
            state,
            self_contact: true,
            friction: 0.0,
            device: None,
        })
    }

    /// Whether the contact local step keeps this membrane's triangles apart from each other
    /// (when the solver has contact on; default true).
    pub fn self_contact(&self) -> bool {
        self.self_contact
    }

    pub fn set_self_contact(&mut self, on: bool) {
        self.self_contact = on;
    }

    /// The Coulomb friction coefficient of this membrane against membranes (itself included) in
    /// the contact local step (dimensionless; default 0, frictionless). A pair of primitives
    /// takes the geometric mean of its two bodies' coefficients (see
    /// `contact::local_step::friction`).
    pub fn friction(&self) -> f64 {
        self.friction
    }

    /// Sets [`Self::friction`]; fails, naming the value, unless it is finite and `>= 0`.
    pub fn set_friction(&mut self, mu: f64) -> Result<()> {
        self.friction = check_param("friction", mu, |m| m >= 0.0, "a finite coefficient >= 0")?;
        Ok(())
    }

    /// A process-unique identity, so a solver can tell whether its cached rest data still match.
    pub fn id(&self) -> u64 {
        self.id
    }
    pub fn mesh(&self) -> &TriangleMesh {
        &self.mesh
    }
    pub fn neighborhood(&self) -> &Neighborhood {
        &self.neighborhood
    }
    pub fn params(&self) -> &MembraneParams {
        &self.params
    }
    /// The source of this membrane's rest data (computed a vertex at a time).
    pub fn rest_source(&self) -> Result<RestSource<'_>> {
        RestSource::new(&self.mesh, &self.neighborhood, &self.params)
    }
    /// Lumped vertex volumes `V_i = thickness * area_i` (m^3).
    pub fn volumes(&self) -> Vec<f64> {
        lumped_volumes(&self.mesh, self.params.thickness)
    }
    /// Lumped vertex masses `m_i = density * V_i` (kg).
    pub fn masses(&self) -> Vec<f64> {
        let density = self.params.density;
        self.volumes().iter().map(|v| density * v).collect()
    }
    pub fn num_vertices(&self) -> usize {
        self.state.len()
    }
    /// Positions (m) as of the last [`Self::sync`] when a GPU step left newer ones on its
    /// device (the Python layer syncs before every access).
    pub fn positions(&self) -> &[Vector3<f64>] {
        debug_assert!(!self.is_pending(), "call Membrane::sync after a GPU step");
        &self.state.positions
    }
    /// Velocities (m/s); see [`Self::positions`].
    pub fn velocities(&self) -> &[Vector3<f64>] {
        debug_assert!(!self.is_pending(), "call Membrane::sync after a GPU step");
        &self.state.velocities
    }

    /// Whether a GPU step left positions and velocities on its device that are newer than
    /// the membrane's own.
    pub fn is_pending(&self) -> bool {
        self.device.as_ref().is_some_and(DeviceCopy::is_pending)
    }

    /// Reads positions and velocities back from the device a GPU step left them on (nothing
    /// when they are current).
    pub fn sync(&mut self) -> Result<()> {
        if let Some(fetch) = self.device.as_mut().and_then(|d| d.fetch.take()) {
            match fetch() {
                Ok((positions, velocities)) => {
                    self.state.positions = positions;
                    self.state.velocities = velocities;
                }
                Err(e) => {
                    // still pending: a later sync may succeed
                    if let Some(d) = self.device.as_mut() {
                        d.fetch = Some(fetch);
                    }
                    return Err(e);
                }
            }
        }
        Ok(())
    }

    /// The device buffers that hold a copy of this membrane's state (`owner`, `epoch`), if its
    /// state has not been replaced since.
    pub fn device_copy(&self) -> Option<(u64, u64)> {
        self.device.as_ref().map(|d| (d.owner, d.epoch))
    }

    /// Records that a GPU step left this membrane's state on its device.
    pub fn leave_on_device(&mut self, copy: DeviceCopy) {
        self.device = Some(copy);
    }

    /// Replaces the positions (m); every value must be finite.
    pub fn set_positions(&mut self, positions: Vec<Vector3<f64>>) -> Result<()> {
        self.state.check_field("positions", "vertex", &positions)?;
        self.sync()?;
        self.state.positions = positions;
        self.device = None;
        Ok(())
    }

    /// Replaces the velocities (m/s); every value must be finite.
    pub fn set_velocities(&mut self, velocities: Vec<Vector3<f64>>) -> Result<()> {
        self.state
            .check_field("velocities", "vertex", &velocities)?;
        self.sync()?;
        self.state.velocities = velocities;
        self.device = None;
        Ok(())
    }

    /// Solver write-back of a finished step (already known to be finite): the host copy is
    /// the newest.
    pub(crate) fn state_mut(&mut self) -> (&mut [Vector3<f64>], &mut [Vector3<f64>]) {
        self.device = None;
        (&mut self.state.positions, &mut self.state.velocities)
    }

    /// Pins vertices at `targets` (default: their current positions).
    pub fn pin(&mut self, indices: &[i64], targets: Option<&[Vector3<f64>]>) -> Result<()> {
        self.state.check_pins("vertex", indices, targets)?;
        if targets.is_none() {
            self.sync()?;
        }
        self.state.insert_pins(indices, targets);
        Ok(())
    }

    /// Releases the given vertices (all when `None`); unknown indices are an error.
    pub fn unpin(&mut self, indices: Option<&[i64]>) -> Result<()> {
        self.state.unpin("vertex", indices)
    }

    /// Pinned vertices and their targets, in ascending vertex order.
    pub fn pins(&self) -> &BTreeMap<u32, Vector3<f64>> {
        &self.state.pins
    }

    /// Moves the pinned vertices' targets (in ascending vertex order).
    pub fn set_pin_targets(&mut self, targets: &[Vector3<f64>]) -> Result<()> {
        self.state.set_pin_targets(targets)
    }

    /// Runs the vertex kernel on every vertex at the current positions, each vertex's rest
    /// data computed on the fly (no per-bond rest data of the whole membrane is held).
    fn evaluate(&self, bond_grad: &mut [Vector3<f64>]) -> Result<Vec<VertexResponse<f64>>> {
        let nb = &self.neighborhood;
        let y = self.positions();
        let source = self.rest_source()?;
        let zero = VertexResponse {
            stretch: 0.0,
            bending: 0.0,
            hourglass: 0.0,
            precond: SymmetricMatrix3::zeros(),
        };
        let mut out = vec![Ok(zero); y.len()];
        for_each_vertex(&nb.offsets, bond_grad, &mut out, &|i, grads| {
            let rest = source.vertex(i)?;
            bond_vectors(i, y, nb.of(i), grads);
            Ok(vertex_kernel(
                &rest.stencil(),
                Preconditioner::default(),
                grads,
            ))
        });
        out.into_iter().collect()
    }

    /// Elastic energy at the current positions, by term (J).
    pub fn energy_terms(&self) -> Result<EnergyTerms> {
        let mut grads = vec![Vector3::zeros(); self.neighborhood.indices.len()];
        Ok(self
            .evaluate(&mut grads)?
            .iter()
            .fold(EnergyTerms::default(), |acc, r| EnergyTerms {
                stretch: acc.stretch + r.stretch,
                bending: acc.bending + r.bending,
                hourglass: acc.hourglass + r.hourglass,
            }))
    }

    /// Internal forces `-dE/dy` at the current positions (N).
    pub fn internal_forces(&self) -> Result<Vec<Vector3<f64>>> {
        let mut grads = vec![Vector3::zeros(); self.neighborhood.indices.len()];
        self.evaluate(&mut grads)?;
        Ok((0..self.num_vertices())
            .map(|k| internal_force(k, &self.neighborhood, &grads))
            .collect())
    }

    /// Principal stretches per vertex (two in-plane, descending, then the normal one).
    pub fn stretches(&self) -> Result<Vec<[f64; 3]>> {
        let nb = &self.neighborhood;
        let source = self.rest_source()?;
        let mut edges = Vec::new();
        (0..self.num_vertices())
            .map(|i| {
                edges.resize(nb.of(i).len(), Vector3::zeros());
                bond_vectors(i, self.positions(), nb.of(i), &mut edges);
                Ok(Deformation::of(&edges, &source.vertex(i)?.stencil()).stretches())
            })
            .collect()
    }

    /// Kinetic energy (J).
    pub fn kinetic_energy(&self) -> f64 {
        self.velocities()
            .iter()
            .zip(self.masses())
            .map(|(v, m)| 0.5 * m * v.norm_squared())
            .sum()
    }
}

/// Internal force on vertex `k` from the bond gradients `t_ij = dE_i/d(y_j - y_i)`:
/// `f_k = sum_j (t_kj - t_jk)` over the (symmetric) neighbourhood.
#[inline]
pub fn internal_force<T: crate::real::Real>(
    k: usize,
    nb: &Neighborhood,
    bond_grad: &[Vector3<T>],
) -> Vector3<T> {
    let bonds = nb.bonds(k);
    let mut f = Vector3::zeros();
    for (g, &reverse) in bond_grad[bonds.clone()].iter().zip(&nb.reverse[bonds]) {
        f += g - bond_grad[reverse as usize];
    }
    f
}
