"""A deterministic Whitted integrator built from Mitsuba 3's own parts, and a renderer around it.

Usage: python mitsuba_whitted.py SCENE.xml OUT.exr [--variant llvm_ad_rgb|scalar_rgb]
                                 [--integrator whitted|wavefront|path|direct]

The scene comes from `rayproof export --to mitsuba`. The integrator does what rayproof's does:
- camera rays from `sensor.sample_ray` (Mitsuba's render loop, stratified cell centres, box filter);
- `scene.ray_intersect` for the first hit;
- at a smooth (diffuse) surface: every point light by `emitter.sample_direction`, visibility by
  `scene.ray_test` (or, with glass_shadows = transmissive, a walk that passes through dielectrics
  unrefracted, as POV-Ray does), `bsdf.eval` for rho/pi cos; then stop;
- at a delta reflector (conductor): follow `bsdf.sample`, weighted by its value;
- at a dielectric: BOTH branches, reflection (weight R) and transmission (weight T, with Mitsuba's
  own eta^2 radiance scaling, which cancels for closed objects), each sampled from `bsdf.sample`
  with the context restricted to that lobe;
- `max_depth` ray segments, black past the cap (POV-Ray's max_trace_level).

JIT variants (llvm) trace wavefronts. `--integrator whitted` (the default, and what the references
were made with) recurses per branch: each branch of each depth is its own batch, compacted
(`dr.compress`) before it is traced, so at depth 10 a frame launches thousands of kernels, most on
a handful of rays. `--integrator wavefront` computes the same sum with one wavefront per depth:
the reflected and the transmitted rays of every glass hit join a single batch, each carrying its
path weight and its camera sample, and radiance is added into the camera sample
(`dr.scatter_reduce`); the image is the same up to float32 rounding. The scalar variant runs the
recursion one ray at a time whatever is asked.

`--integrator path` or `direct` renders the same scene with Mitsuba's stock integrator instead
(`path` at the scene's max_depth, Russian roulette off below it): Mitsuba's own fastest
configurations, for timing only. They do not make the Whitted image (path adds diffuse
interreflection, direct has no mirror or glass paths).
"""
import re
import sys

import drjit as dr
import mitsuba as mi


def lobe_ctx(flag):
    """A BSDF context that enables only one lobe type."""
    ctx = mi.BSDFContext()
    ctx.type_mask = int(flag)
    return ctx


class Whitted:
    """The shading rules; `jit` chooses batched (compacted) or one-ray recursion."""

    def __init__(self, max_depth, transmissive_shadows, jit):
        self.max_depth = max_depth
        self.transmissive = transmissive_shadows
        self.jit = jit

    def no(self, m):
        """Logical not of a mask (a JIT array or, in scalar variants, a Python bool)."""
        return ~m if self.jit else not m

    def visible(self, scene, si, ds, active):
        """Is the light at ds.p visible from si? Glass is opaque, or passed straight through."""
        ray = si.spawn_ray_to(ds.p)
        if not self.transmissive:
            return active & self.no(scene.ray_test(ray, active))
        # Walk through dielectric surfaces along the unrefracted segment (at most 32 crossings)
        vis = mi.Bool(active)
        for _ in range(32):
            hit = scene.ray_intersect(ray, vis)
            blocked = hit.is_valid()
            if not self.jit and not (vis and blocked):
                break  # scalar: nothing in the way (or already blocked)
            glass = mi.has_flag(hit.bsdf(ray).flags(), mi.BSDFFlags.DeltaTransmission)
            vis = vis & self.no(blocked & self.no(glass))
            go_on = vis & blocked & glass
            if self.jit:
                if not dr.any(go_on):
                    break
            elif not go_on:
                break
            ray = dr.select(go_on, hit.spawn_ray_to(ds.p), ray)
            vis = vis & (go_on | self.no(blocked))
        return vis

    def direct(self, scene, si, bsdf, active):
        """Sum over point lights of bsdf.eval (rho/pi cos) times I/d^2, if visible."""
        L = mi.Color3f(0.0)
        ctx = mi.BSDFContext()
        for em in scene.emitters():
            ds, w = em.sample_direction(si, mi.Point2f(0.5, 0.5), active)
            vis = self.visible(scene, si, ds, active & (ds.pdf > 0))
            f = bsdf.eval(ctx, si, si.to_local(ds.d), vis)
            L += dr.select(vis, f * w, 0.0)
        return L

    def radiance(self, scene, ray, depth, active):
        """Radiance along rays at segment `depth` (1 = camera ray)."""
        si = scene.ray_intersect(ray, active)
        active = active & si.is_valid()
        if not self.jit and not active:
            return mi.Color3f(0.0)  # scalar: no shape, no BSDF to ask
        bsdf = si.bsdf(ray)
        flags = bsdf.flags()
        smooth = active & mi.has_flag(flags, mi.BSDFFlags.Smooth)
        L = self.direct(scene, si, bsdf, smooth)
        if depth >= self.max_depth:
            return L
        delta = active & self.no(mi.has_flag(flags, mi.BSDFFlags.Smooth))
        for flag in (mi.BSDFFlags.DeltaReflection, mi.BSDFFlags.DeltaTransmission):
            bs, w = bsdf.sample(lobe_ctx(flag), si, 0.5, mi.Point2f(0.5, 0.5), delta)
            go = delta & (bs.pdf > 0) & dr.any(w > 0)
            child = si.spawn_ray(si.to_world(bs.wo))
            L += self.branch(scene, child, w, depth + 1, go)
        return L

    def wavefront(self, scene, ray):
        """Radiance along camera rays, one batch per depth for every branch (JIT variants)."""
        n = dr.width(ray.d.x)
        L = dr.zeros(mi.Color3f, n)
        pix = dr.arange(mi.UInt32, n)  # the camera sample each ray adds into
        w = dr.full(mi.Color3f, 1.0, n)  # its path weight
        for depth in range(1, self.max_depth + 1):
            m = dr.width(pix)
            si = scene.ray_intersect(ray, dr.full(mi.Bool, True, m))
            valid = si.is_valid()
            bsdf = si.bsdf(ray)
            flags = bsdf.flags()
            smooth = valid & mi.has_flag(flags, mi.BSDFFlags.Smooth)
            dr.scatter_reduce(dr.ReduceOp.Add, L, w * self.direct(scene, si, bsdf, smooth), pix, smooth)
            dr.schedule(L)
            if depth >= self.max_depth:
                break
            # Both delta lobes of every ray; lanes [0, m) reflect, [m, 2m) transmit
            delta = valid & ~mi.has_flag(flags, mi.BSDFFlags.Smooth)
            lobes = []
            for flag in (mi.BSDFFlags.DeltaReflection, mi.BSDFFlags.DeltaTransmission):
                bs, wb = bsdf.sample(lobe_ctx(flag), si, 0.5, mi.Point2f(0.5, 0.5), delta)
                go = delta & (bs.pdf > 0) & dr.any(wb > 0)
                lobes.append((go, si.spawn_ray(si.to_world(bs.wo)), w * wb))
            (go_r, ray_r, w_r), (go_t, ray_t, w_t) = lobes
            lane = dr.arange(mi.UInt32, 2 * m)
            second = lane >= m
            src = dr.select(second, lane - m, lane)
            go = dr.select(second, dr.gather(mi.Bool, go_t, src), dr.gather(mi.Bool, go_r, src))
            # The survivors of both lobes: the next depth's one wavefront
            keep = dr.compress(go)
            if dr.width(keep) == 0:
                break
            k_src = dr.gather(mi.UInt32, src, keep)
            k_t = dr.gather(mi.Bool, second, keep)

            def pick(T, r, t):
                return dr.select(k_t, dr.gather(T, t, k_src), dr.gather(T, r, k_src))

            ray = mi.Ray3f(pick(mi.Point3f, ray_r.o, ray_t.o), pick(mi.Vector3f, ray_r.d, ray_t.d))
            w = pick(mi.Color3f, w_r, w_t)
            pix = dr.gather(mi.UInt32, pix, k_src)
            dr.eval(ray, w, pix)
        dr.eval(L)
        return L

    def branch(self, scene, ray, w, depth, go):
        """w times the radiance of the rays where `go`, traced as a compacted batch."""
        if not self.jit:
            return w * self.radiance(scene, ray, depth, go) if go else mi.Color3f(0.0)
        idx = dr.compress(go)
        n = dr.width(idx)
        if n == 0:
            return mi.Color3f(0.0)
        sub = dr.gather(mi.Ray3f, ray, idx)
        Ls = dr.gather(mi.Color3f, w, idx) * self.radiance(scene, sub, depth, dr.full(mi.Bool, True, n))
        dr.eval(Ls)
        out = dr.zeros(mi.Color3f, dr.width(go))
        dr.scatter_reduce(dr.ReduceOp.Add, out, Ls, idx)
        return out


def register():
    """Registers the 'whitted' integrator (after mi.set_variant, which defines the base class)."""

    class WhittedIntegrator(mi.SamplingIntegrator):
        def __init__(self, props):
            mi.SamplingIntegrator.__init__(self, props)
            self.max_depth = props.get("max_depth", 10)
            self.shadows = props.get("glass_shadows", "opaque")
            self.one_wavefront = False  # set by main() for --integrator wavefront

        def sample(self, scene, sampler, ray, medium=None, active=True):
            jit = dr.is_jit_v(mi.Float)
            w = Whitted(self.max_depth, self.shadows == "transmissive", jit)
            ray = mi.Ray3f(ray)
            if jit and self.one_wavefront:
                return w.wavefront(scene, ray), mi.Bool(True), []
            L = w.radiance(scene, ray, 1, mi.Bool(active))
            return L, mi.Bool(True), []

        def aov_names(self):
            return []

        def to_string(self):
            return f"Whitted[max_depth={self.max_depth}, glass_shadows={self.shadows}]"

    made = []
    mi.register_integrator("whitted", lambda props: made.append(WhittedIntegrator(props)) or made[-1])
    return made


def main(argv):
    import argparse
    import time

    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("scene")
    ap.add_argument("output")
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--integrator", default="whitted", choices=["whitted", "wavefront", "path", "direct"])
    a = ap.parse_args(argv)
    mi.set_variant(a.variant)
    made = register()
    scene = mi.load_file(a.scene)
    integrator = None
    if a.integrator == "wavefront":
        made[-1].one_wavefront = True
    elif a.integrator == "path":
        # The scene's depth, no Russian roulette before it
        depth = int(re.search(r'name="max_depth" value="(\d+)"', open(a.scene).read()).group(1))
        integrator = mi.load_dict({"type": "path", "max_depth": depth, "rr_depth": depth})
    elif a.integrator == "direct":
        integrator = mi.load_dict({"type": "direct"})
    start = time.perf_counter()
    img = mi.render(scene, integrator=integrator)
    dr.eval(img)
    secs = time.perf_counter() - start
    mi.Bitmap(img).write(a.output)
    print(f"mitsuba {mi.__version__} {a.variant} {a.integrator}: {a.output} in {secs:.2f} s")


if __name__ == "__main__":
    main(sys.argv[1:])
