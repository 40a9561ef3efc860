"""Visibility edges (the package docstring, "Pairs"): silhouettes of spheres (and
ellipsoids), outlines of flat meshes and creases; where two samples see different surfaces
(:meth:`Visibility.surface_differs`), and g of such a pair (:meth:`Visibility.visibility`):
the primitives' inside functions (:meth:`Visibility.inside`, which the shadow edges' g reads
too), the edge of a face that flips, the distance to a primitive (a crease's g). The same
function serves the visibility edges seen along the specular chain (``chain.py``)."""

import drjit as dr
import mitsuba as mi
import numpy as np

from ..arrays import jit_array
from ..hits import MESH, NO_NEIGHBOUR, PLANE, SMOOTH, SPHERE
from .lattice import CREASE, NO_HIT, STOP, VISIBILITY, across_crease, at
from .terms import at_l_and_r, on_lanes, signs_differ, stacked

COPLANAR = 1e-5  # faces whose unit normals differ by less than this are one surface
# how near zero the crease's g must be where, taken as linear, it vanishes between L and R
# (in multiples of the smaller of its values at L and R), for the crease to be the edge
CREASE_ZERO = 0.25
# the most faces of a mesh past its own that a pair's segment is followed across, to the
# mesh's outline (Visibility.outline)
WALK = 8


class Faces:
    """Primitives (shape, prim), one per lane (numpy ids; NO_HIT: none), on the device once
    for every function of them that g reads (:meth:`Boundary.inside`, :meth:`Boundary.depth`,
    :meth:`Boundary.crossed_edge`): whether there is one (``valid``), its kind bits and first
    row in the geometry table ``table``, and the primitive (UInt32)."""

    def __init__(self, table, shape, prim):
        ids = jit_array(mi.UInt32, np.where(shape == NO_HIT, 0, shape).astype(np.uint32))
        self.valid, self.kind, self.row = table.entries(ids, jit_array(mi.Bool, shape != NO_HIT))
        self.prim = jit_array(mi.UInt32, prim.astype(np.uint32))

    def with_prim(self, prim):
        """The same shapes' primitives ``prim`` (a UInt32 per lane, on the device)."""
        out = object.__new__(Faces)
        out.valid, out.kind, out.row, out.prim = self.valid, self.kind, self.row, prim
        return out


class Visibility:
    """The visibility edges of :class:`Boundary` (a mixin of Boundary)."""

    def surface_differs(self, shape, prim, normal, L, R):
        """Whether the samples of the pairs (L, R) (numpy flat positions, see :func:`flat`)
        see different surfaces, by the lattice's keys ``shape``, ``prim`` and ``normal``
        (the face's normal: x, y, z planes) of the first hit or of a bounce of the chain:
        another shape (or one a miss, or a chain that ended), another face of a flat mesh
        that is not coplanar with the first (a glass box's faces, seen from inside along the
        chain), or a face of a smooth mesh across a crease (a tessellated cylinder's or
        cone's cap and side: one mesh, whose vertex normals jump at the rim, and the shading
        with them), where the faces' normals differ by more than CREASE."""
        sl, sr = at(shape, L), at(shape, R)
        differs = sl != sr
        faces = ~differs & (sl < STOP) & (at(prim, L) != at(prim, R))
        if not faces.any():
            return differs
        kind = self.kinds(sl[faces])
        mesh, smooth = kind & MESH != 0, kind & SMOOTH != 0
        where = np.flatnonzero(faces)[mesh]
        nl, nr = (np.stack([at(c, side[where]) for c in normal], -1) for side in (L, R))
        apart = np.where(smooth[mesh], across_crease(nl, nr),
                         np.linalg.norm(nl - nr, axis=-1) > COPLANAR)
        differs[where[apart]] = True
        return differs

    def visibility(self, table, ray, left, right, choices, name):
        """g of a visibility edge between the rays of L and R (of the stacked rays ``ray``),
        which see (shape, prim, t) ``left`` and ``right`` (per pair): N is the nearer; the
        difference of the two primitives' distances where a crease between them comes first
        (:meth:`crease_first`), else N's inside function where the other ray's line misses
        N's primitive (of a mesh, the face and edge where the segment between L and R leaves
        the mesh: :meth:`outline`), else the other's, else (a crease) the difference of the
        two primitives' distances. ``choices``: see
        g_at (theirs: under ``name``; "first": the camera's rays, whose origin is the eye,
        else rays that start on a surface: see :meth:`edge_functions`)."""
        lanes = dr.width(ray.d)
        from_eye = name == "first"
        near_is_l = left[2] <= right[2]
        n_shape, n_prim = (np.where(near_is_l, a, b) for a, b in zip(left[:2], right[:2]))
        f_shape, f_prim = (np.where(near_is_l, b, a) for a, b in zip(left[:2], right[:2]))
        made = choices.get((name, "visibility"))
        if made is None:  # the crease where it lies on both, else N's function where its
            # sign differs between L and R, else F's
            near, far = Faces(table, n_shape, n_prim), Faces(table, f_shape, f_prim)
            f_edge = self.crossed_edge(table, ray, far, from_eye)
            two = jit_array(mi.Bool, f_shape < STOP)  # (F a surface, not a miss)
            # (two shapes, both flat: faces of one mesh meet at their edges, which are the
            # crease; a sphere's distance off its outline is not its own, see crease_first)
            flat = two & jit_array(mi.Bool, n_shape != f_shape) & ~self.curved(near) & \
                ~self.curved(far)
            # N's face and edge where the segment leaves N's mesh, or dips behind F's
            # surface (the crease), not merely where it leaves N's own face: of the
            # camera's rays only (along the chain an outline so found has its color traced
            # at the outline, whose squeezed band Terms.jump does not replace by the
            # sample's there: a glass cone's and a cone in a mirror floor's camera keys,
            # seeds 22 and 28 of benchmarks/random_edges.py, lost 1-5 points with it)
            if from_eye:
                near, n_edge, n_walked = self.outline(table, ray, near, from_eye, far, flat)
            else:
                n_edge, n_walked = self.crossed_edge(table, ray, near, from_eye), None
            with dr.suspend_grad():
                ends = at_l_and_r(ray, len(f_shape))
                use_crease = flat & self.crease_first(table, ends, near, far, from_eye)
                g_l, g_r = ([self.inside(table, rays, faces, edge, from_eye)
                             for faces, edge in ((near, n_edge), (far, f_edge))]
                            for rays in ends)
            use_n = ~use_crease & signs_differ(g_l[0], g_r[0])
            use_f = ~use_crease & ~use_n & two & signs_differ(g_l[1], g_r[1])
            choices[(name, "visibility")] = (n_walked, n_edge, f_edge, use_n, use_f)
        else:
            n_walked, n_edge, f_edge, use_n, use_f = made
        near, far = (Faces(table, stacked(shape, lanes), stacked(prim, lanes))
                     for shape, prim in ((n_shape, n_prim), (f_shape, f_prim)))
        if n_walked is not None:  # (N's faces followed to the mesh's outline: outline)
            near = near.with_prim(on_lanes(n_walked, lanes))
        gn = self.inside(table, ray, near, on_lanes(n_edge, lanes), from_eye)
        gf = self.inside(table, ray, far, on_lanes(f_edge, lanes), from_eye)
        return dr.select(on_lanes(use_n, lanes), gn,
                         dr.select(on_lanes(use_f, lanes), gf,
                                   self.crease(table, ray, near, far)))

    @staticmethod
    def followed(ends, kind, choices):
        """Per pair (numpy bool): whether it is a visibility pair of the surface seen whose
        segment g_at followed past its near sample's face (:meth:`outline`; ``choices``: g_at's,
        made; ``ends``: the pairs' :class:`Ends`)."""
        made = choices.get(("first", "visibility"))
        if made is None or made[0] is None:  # (none followed)
            return np.zeros(len(kind), bool)
        near_prim = np.where(ends.t[0] <= ends.t[1], *ends.prim)
        return (kind == VISIBILITY) & (made[0].numpy() != near_prim.astype(np.uint32))

    def crease_first(self, table, ends, near, far, from_eye):
        """Whether the pairs' edge is the crease where the flat faces N and F (``near``,
        ``far``: :class:`Faces`) meet, by the rays of L and R (``ends``): the crease's g
        (the difference of their distances) changes sign between L and R, and on the ray
        between them where it is zero (taken as linear) both faces are there (their inside
        functions positive) and it is zero indeed (within CREASE_ZERO of the smaller of its
        values at L and R: a plane seen nearly edge-on, whose distance is far from linear,
        finds no crease). A surface through another (a cone through the floor, one of whose
        thin faces L sees while R's line misses that face beyond the floor) then has the
        crease's g, whose normal and rate are the crease's, not those of the face's own
        edge that the line crosses past where it dips under the floor. (Not a sphere: its
        distance is its own only where a ray meets it, and the crease's g is read beside the
        crossing too, for the edge's normal, where a ray may miss it: a sphere
        through a cylinder keeps the outline's g, as before.)"""
        c_l, c_r = (self.crease(table, rays, near, far) for rays in ends)
        w = c_l / (c_l - c_r)  # where the crease's g is zero, from L to R
        ray_l, ray_r = ends
        between = mi.Ray3f(dr.lerp(ray_l.o, ray_r.o, w), dr.lerp(ray_l.d, ray_r.d, w))
        zero = dr.abs(self.crease(table, between, near, far)) < \
            CREASE_ZERO * dr.minimum(dr.abs(c_l), dr.abs(c_r))
        return signs_differ(c_l, c_r) & zero \
            & (self.inside(table, between, near, None, from_eye) > 0) \
            & (self.inside(table, between, far, None, from_eye) > 0)

    def crease(self, table, ray, near, far):
        """A crease's g: the difference of each ray's distances to its primitives ``near``
        and ``far`` (:class:`Faces`)."""
        return self.depth(table, ray, near) - self.depth(table, ray, far)

    @staticmethod
    def curved(faces):
        """Whether each of ``faces``' primitives (:class:`Faces`) is a sphere (or an
        ellipsoid of the sphere set)."""
        return faces.valid & ((faces.kind & SPHERE) != 0)

    def inside(self, table, ray, faces, edge=None, from_eye=False):
        """The inside function of each ray's primitive (``faces``: :class:`Faces`): > 0 where
        the ray meets it (see the package docstring). For a triangle, ``edge`` (an Int32 per
        lane: 0, 1, 2, or -1 for the least of the three) picks the edge function
        (``from_eye``: see :meth:`edge_functions`). An unbounded plane has
        :meth:`towards_plane`, whichever ray sees it: the camera's, or one along the
        specular chain (the horizon seen in a mirror or through glass)."""
        valid, kind, row, prim = faces.valid, faces.kind, faces.row, faces.prim
        out = mi.Float(-1.0)
        d = dr.normalize(ray.d)
        if table.has_spheres:
            sphere = valid & ((kind & SPHERE) != 0)
            oc, d_local, r = self.sphere_frame(table, row, prim, ray.o, d, sphere)
            if table.has_ellipsoids:  # (an ellipsoid's direction in object space: not unit)
                d_local = dr.normalize(d_local)
            out = dr.select(sphere, r - dr.norm(dr.cross(oc, d_local)), out)
        if table.has_meshes:
            mesh = valid & ((kind & MESH) != 0)
            e = self.edge_functions(table, ray, d, row, prim, mesh, from_eye)
            g = dr.minimum(dr.minimum(e[0], e[1]), e[2])
            if edge is not None:
                chosen = dr.select(edge == 0, e[0], dr.select(edge == 1, e[1], e[2]))
                g = dr.select(edge >= 0, chosen, g)
            out = dr.select(mesh, g, out)
            if table.has_planes:  # (an unbounded plane's outline: its horizon)
                plane = mesh & ((kind & PLANE) != 0)
                out = dr.select(plane, self.towards_plane(table, ray, d, row, prim, plane), out)
        return out

    @staticmethod
    def towards_plane(table, ray, d, row, prim, plane):
        """The inside function of an unbounded plane (``hits.PLANE``) for each ray (origin o,
        unit direction ``d``): -(n . (o - p)) (n . d), n the unit normal of its lane's face
        and p a point of it; > 0 where the ray heads towards the plane from the side its
        origin lies on. Zero at the horizon (n . d = 0, where the plane vanishes) and where
        the origin crosses the plane (a surface through the floor, whose part below it sees
        the floor from under it, along the chain or towards a light): a product of the two,
        each factor far from zero where the other crosses it. (Its faces' edges are edges
        of rings that crowd towards the horizon, many to a lattice unit; the one a ray hit
        is not where the plane ends, and moves otherwise: the horizon stays put when the
        eye, or a chain ray's origin, moves.)"""
        _, (p0, p1, p2) = table.corners(row, prim, plane)
        n = dr.normalize(dr.cross(p1 - p0, p2 - p0))
        return -dr.dot(n, ray.o - p0) * dr.dot(n, d)

    @staticmethod
    def sphere_frame(table, row, prim, o, d, sphere):
        """Each lane's ray (o, d) in the frame of its sphere (``HitTable.sphere_frame``):
        row ``row + prim`` (UInt32 ``prim``: 0 for a Mitsuba sphere, the sphere's index in a
        sphere set)."""
        return table.sphere_frame(row + prim, o, d, sphere)

    def edge_functions(self, table, ray, d, row, prim, mesh, from_eye=False):
        """The three normalized edge functions of each lane's face, signed to be > 0 inside:
        where the ray meets the face. The sign is the side of the face's plane the ray comes
        from: for the camera's rays (``from_eye``), the side its origin lies on; for rays that
        start on a surface (along the specular chain, to a light), the side its direction
        points away from. (The eye lies on no face's plane, while the sign of a direction
        against a face's normal flips between two rays of a pair that both miss the face
        seen edge-on: the plane's far ring at the horizon, whose miss rays point above its
        vanishing line by a millionth of a radian. A surface point may lie near another
        face's plane, and two rays of a pair then start either side of it.)"""
        _, (p0, p1, p2) = table.corners(row, prim, mesh)
        normal = dr.detach(dr.cross(p1 - p0, p2 - p0))
        if from_eye:
            sigma = dr.select(dr.dot(normal, dr.detach(ray.o - p0)) >= 0, -1.0, 1.0)
        else:
            sigma = dr.select(dr.dot(normal, dr.detach(d)) <= 0, -1.0, 1.0)
        return [sigma * dr.dot(dr.cross(a - ray.o, b - ray.o), d) / dr.norm(b - a)
                for a, b in ((p0, p1), (p1, p2), (p2, p0))]

    def crossed_edge(self, table, ray, faces, from_eye=False):
        """Per pair (an Int32 of P lanes, on the device): the edge of its face (``faces``:
        :class:`Faces`, one per pair) through which the segment between the rays of L and R
        (of the stacked rays ``ray``) leaves or enters the face: of the edges whose function
        changes sign between them, the one whose sign changes nearest the inside end (the
        functions taken as linear along the segment; ``from_eye``: see :meth:`edge_functions`);
        -1: none, or not a face. (Not merely
        the first that flips: the line of another edge may also pass between L and R -- a
        tessellation's thin triangles, whose long edges run side by side -- and crossing
        that line is no edge of the surface.)"""
        count = dr.width(faces.prim)
        if not table.has_meshes:
            return dr.full(mi.Int32, -1, count)
        with dr.suspend_grad():
            mesh = faces.valid & ((faces.kind & MESH) != 0)
            sides = self.edges_at_ends(table, ray, faces, mesh, from_eye)
            return dr.select(mesh, self.leaving(sides, self.l_inside(sides))[0], -1)

    @staticmethod
    def l_inside(sides):
        """Whether L is the end of each pair inside its face (``sides``: the edge functions
        at L and R, :meth:`edges_at_ends`): the end where the least of the three is the
        larger."""
        return dr.minimum(dr.minimum(sides[0][0], sides[0][1]), sides[0][2]) >= \
            dr.minimum(dr.minimum(sides[1][0], sides[1][1]), sides[1][2])

    def edges_at_ends(self, table, ray, faces, mesh, from_eye):
        """The three edge functions (:meth:`edge_functions`) of each pair's face (``faces``,
        where ``mesh``) at L's and at R's rays (of the stacked rays ``ray``), detached: [L's
        three, R's three]."""
        sides = []
        for rays in at_l_and_r(ray, dr.width(faces.prim)):  # (L's, then R's)
            d = dr.normalize(dr.detach(rays.d))
            rays = mi.Ray3f(dr.detach(rays.o), d)
            sides.append(self.edge_functions(table, rays, d, faces.row, faces.prim, mesh,
                                             from_eye))
        return sides

    @staticmethod
    def leaving(sides, l_inside, entered=False):
        """(edge, at): the edge (Int32: 0, 1, 2; -1: none) through which the segment from
        the inside end (L where ``l_inside``, else R) leaves the face whose edge functions at
        the ends are ``sides`` (:meth:`edges_at_ends`), or enters it: of those whose sign
        differs between the ends, the one whose zero (the functions taken as linear) lies
        nearest the inside end; and that zero, as a fraction of the way from the inside end.
        ``entered``: the inside end lies outside the face (a face the segment was followed
        into, :meth:`outline`), and only an edge whose function is >= 0 there, one the
        segment leaves by, counts."""
        edge, nearest = mi.Int32(-1), mi.Float(dr.inf)
        for i in (0, 1, 2):
            a, b = sides[0][i], sides[1][i]
            at = a / (a - b)  # where the function is zero, from L (0) to R (1)
            from_inside = dr.select(l_inside, at, 1.0 - at)
            better = signs_differ(a, b) & (from_inside < nearest)
            if entered:
                better &= dr.select(l_inside, a, b) >= 0
            edge = dr.select(better, i, edge)
            nearest = dr.select(better, from_inside, nearest)
        return edge, nearest

    def outline(self, table, ray, faces, from_eye=False, far=None, flat=None):
        """(faces, edge, walked) where each pair's segment leaves its face's mesh (``faces``:
        :class:`Faces`; ``walked``: their primitives, a UInt32 per pair, where the walk below
        ran, else None: every pair's face is its own), starting from the edge through which it leaves that face
        (:meth:`crossed_edge`'s, found here with where along the segment it lies). Where
        that edge is no edge of the surface's -- another face of the mesh shares it
        (``HitTable.neighbours``), the segment goes on into it, and the look does not jump
        there (:meth:`goes_on`) -- the segment is followed into that face, to the edge it
        leaves it by, up to WALK faces; it stops at an outline (the
        mesh's border, or a fold: a closed mesh's silhouette), at a crease (whose own jump,
        between L's face and the next, no pair then has: the lattice's error where two
        edges share a pair, which falls with k), where it would end inside a face, and
        where the mesh goes behind the other sample's surface (``far``, where ``flat``:
        the two distances' difference changes sign between the inside end and where the
        segment leaves the face: the crease between them is the edge, see
        :meth:`crease_first`). (A tessellated cylinder's cap is a fan of thin triangles: at
        its rim, a segment from a sample on the cap to one beyond it may leave the sample's
        face through a spoke, whose line is no edge and moves as the spoke does; the rim is
        where it leaves the next face.)"""
        if not table.has_meshes:
            return faces, dr.full(mi.Int32, -1, dr.width(faces.prim)), None
        with dr.suspend_grad():
            mesh = faces.valid & ((faces.kind & MESH) != 0)
            sides = self.edges_at_ends(table, ray, faces, mesh, from_eye)
            l_inside = self.l_inside(sides)
            edge, leaves_at = self.leaving(sides, l_inside)
            edge = dr.select(mesh, edge, -1)  # (crossed_edge's)
            mesh &= (faces.kind & PLANE) == 0  # (an unbounded plane's outline: its horizon)
            ray_l, ray_r = (mi.Ray3f(dr.detach(r.o), dr.detach(r.d))
                            for r in at_l_and_r(ray, dr.width(faces.prim)))
            start = mi.Ray3f(dr.select(l_inside, ray_l.o, ray_r.o),
                             dr.select(l_inside, ray_l.d, ray_r.d))
            prim, active, walked = faces.prim, mesh & (edge >= 0), False
            for _ in range(WALK):
                if not dr.any(active):
                    break
                walked = True
                if far is not None:  # (not past where the mesh dips behind F's surface)
                    active &= ~(flat & self.dips_behind(table, faces.with_prim(prim), far, start,
                                                        ray_l, ray_r, l_inside, leaves_at))
                there = dr.gather(mi.UInt32, table.neighbours(),
                                  (faces.row + prim) * 3 + mi.UInt32(dr.maximum(edge, 0)), active)
                active &= there != NO_NEIGHBOUR
                active &= self.goes_on(table, faces, prim, there, edge, start.o, active)
                sides = self.edges_at_ends(table, ray, faces.with_prim(there), active, from_eye)
                leaves, at = self.leaving(sides, l_inside, entered=True)
                active &= leaves >= 0
                prim = dr.select(active, there, prim)
                edge = dr.select(active, leaves, edge)
                leaves_at = dr.select(active, at, leaves_at)
            if not walked:
                return faces, edge, None
            return faces.with_prim(prim), edge, prim

    def dips_behind(self, table, near, far, start, ray_l, ray_r, l_inside, leaves_at):
        """Whether each pair's face ``near`` goes behind ``far``'s surface (:class:`Faces`)
        between the segment's inside end (the ray ``start``) and where the segment leaves
        the face (``leaves_at``, a fraction of the way from the inside end; the rays of L
        and R: ``ray_l``, ``ray_r``): the crease's g changes sign between them."""
        w = dr.select(l_inside, leaves_at, 1.0 - leaves_at)  # (from L)
        leaving = mi.Ray3f(dr.lerp(ray_l.o, ray_r.o, w), dr.lerp(ray_l.d, ray_r.d, w))
        return signs_differ(self.crease(table, start, near, far),
                            self.crease(table, leaving, near, far))

    @staticmethod
    def goes_on(table, faces, prim, there, edge, o, active):
        """Whether a segment that leaves each lane's face ``prim`` of its mesh (``faces``:
        :class:`Faces`, for the mesh's kind and first face) through its edge ``edge`` goes
        on, unbroken, into the face ``there`` that shares the edge: the two lie either side
        of it as seen from ``o`` (their centroids either side of the plane through ``o`` and
        the edge, whatever their winding: not a fold, where a closed mesh's outline is), and
        the surface's look does not jump there (a smooth mesh's faces within CREASE of each
        other, a flat mesh's coplanar: not a crease, whose jump is an edge of its own)."""
        _, (p0, p1, p2) = table.corners(faces.row, prim, active)
        _, (q0, q1, q2) = table.corners(faces.row, there, active)
        a = dr.select(edge == 0, p0, dr.select(edge == 1, p1, p2))
        b = dr.select(edge == 0, p1, dr.select(edge == 1, p2, p0))
        m = dr.cross(a - o, b - o)
        either_side = dr.dot(m, (p0 + p1 + p2) / 3.0 - o) * dr.dot(m, (q0 + q1 + q2) / 3.0 - o) < 0
        n_here = dr.normalize(dr.cross(p1 - p0, p2 - p0))
        n_there = dr.normalize(dr.cross(q1 - q0, q2 - q0))
        unbroken = dr.select((faces.kind & SMOOTH) != 0, dr.dot(n_here, n_there) >= CREASE,
                             dr.norm(n_here - n_there) <= COPLANAR)
        return either_side & unbroken

    def depth(self, table, ray, faces):
        """The distance along each ray to its primitive's (``faces``: :class:`Faces`) plane
        or sphere."""
        valid, kind, row, prim = faces.valid, faces.kind, faces.row, faces.prim
        out = mi.Float(0.0)
        if table.has_spheres:
            sphere = valid & ((kind & SPHERE) != 0)
            oc, d, r = self.sphere_frame(table, row, prim, ray.o, ray.d, sphere)
            a, b = dr.squared_norm(d), dr.dot(oc, d)
            root = dr.safe_sqrt(dr.square(b) - a * (dr.squared_norm(oc) - dr.square(r)))
            out = dr.select(sphere, (-b - root) / a, out)
        if table.has_meshes:
            mesh = valid & ((kind & MESH) != 0)
            _, (p0, p1, p2) = table.corners(row, prim, mesh)
            n = dr.cross(p1 - p0, p2 - p0)
            out = dr.select(mesh, dr.dot(n, p0 - ray.o) / dr.dot(n, ray.d), out)
        return out
