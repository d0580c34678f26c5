//! Deep shadow lists (after deep shadow maps on the GPU) under GPU-assisted + synchronization
//! validation: the GPU lists against a CPU model of the footprint rule and
//! the allocator (per-texel multisets, order, chunk accounting, links,
//! guards), pool overflow and growth, exact opaque and translucent shadows
//! against CPU shadow rays (f64), and a deep lattice stress case.

mod common;

use common::*;
use glam::DVec3;
use sphereshade::camera::Camera;
use sphereshade::output::ids_from_vis;
use sphereshade::reference;
use sphereshade::render::Renderer;
use sphereshade::scene::{self, Scene, Sphere};
use sphereshade::settings::{RenderSettings, ShadowMode};
use sphereshade::stages::shadows::deep::{self, CHUNK, DeepRaw, NONE, TILE, TILE_OVERFLOWED};
use sphereshade::vk::Context;
use std::collections::{HashMap, HashSet};

/// Disk slack in texels, as DEEP_DISK_SLACK in glsl/deep.glsl.
const DISK_SLACK: f64 = 0.01;

fn deep_settings(scene: &Scene, w: u32, h: u32, map: u32, opacity: f32) -> RenderSettings {
    let mut s = settings(camera(scene, w, h, None), ShadowMode::Deep);
    s.issm.size = map;
    s.opacity = opacity;
    // translucent shadows on visible receivers: every sphere drawn opaque
    s.opaque_view = true;
    s
}

/// Depth offset of the light view as the renderer computes it.
fn light_depth_offset(scene: &Scene, light: &Camera) -> f64 {
    let (c, r) = scene.bounding_sphere();
    (c.as_dvec3() - light.center).length() + r as f64 + 1.0
}

/// A CPU entry: sphere id, depth, and whether f32 rounding may decide
/// membership (the disk edge within 1e-3 texel of the square).
#[derive(Clone, Copy, Debug)]
struct CpuEntry {
    id: u32,
    depth: f64,
    ambiguous: bool,
}

/// The footprint rule in f64: every sphere whose light-space disk (radius
/// + slack) overlaps a texel's square gets an entry there.
fn cpu_lists(scene: &Scene, light: &Camera, offset: f64) -> Vec<Vec<CpuEntry>> {
    let (n, h) = (light.width as i64, light.height as i64);
    let ppu = light.pixels_per_unit();
    let mut lists = vec![Vec::new(); (n * h) as usize];
    for (i, s) in scene.spheres.iter().enumerate() {
        let c = DVec3::new(s.center[0] as f64, s.center[1] as f64, s.center[2] as f64);
        let q = c - light.center;
        let (x, y, z) = (q.dot(light.right), q.dot(light.up), q.dot(light.dir));
        let (cx, cy) = (x * ppu + 0.5 * n as f64, 0.5 * h as f64 - y * ppu);
        let rr = s.radius as f64 * ppu + DISK_SLACK;
        let depth = z - s.radius as f64 + offset;
        let x0 = ((cx - rr).floor() as i64 - 1).max(0);
        let x1 = ((cx + rr).floor() as i64 + 1).min(n - 1);
        let y0 = ((cy - rr).floor() as i64 - 1).max(0);
        let y1 = ((cy + rr).floor() as i64 + 1).min(h - 1);
        for ty in y0..=y1 {
            for tx in x0..=x1 {
                let dx = cx.clamp(tx as f64, tx as f64 + 1.0) - cx;
                let dy = cy.clamp(ty as f64, ty as f64 + 1.0) - cy;
                let d = (dx * dx + dy * dy).sqrt();
                if d <= rr + 1e-3 {
                    let ambiguous = (d - rr).abs() <= 1e-3;
                    lists[(ty * n + tx) as usize].push(CpuEntry {
                        id: i as u32,
                        depth,
                        ambiguous,
                    });
                }
            }
        }
    }
    lists
}

/// The greedy epsilon compression of glsl/deep_sort.comp in f32, returning
/// the nodes (depth, V) of V'.
fn compress(list: &[(u32, f32, f32)], eps: f32) -> Vec<(f32, f32)> {
    if list.is_empty() {
        return Vec::new();
    }
    const BIG: f32 = 3.0e38;
    let (mut za, mut va) = (list[0].1, 1.0f32);
    let (mut lo, mut hi, mut zl) = (-BIG, BIG, za);
    let mut open = false;
    let mut nodes = vec![(za, va)];
    let mut feed = |z: f32, v: f32, nodes: &mut Vec<(f32, f32)>| {
        for _ in 0..2 {
            let dz = z - za;
            if dz <= 0.0 {
                if (v - va).abs() > eps {
                    va = v;
                    nodes.push((za, va));
                    lo = -BIG;
                    hi = BIG;
                    open = false;
                }
                return;
            }
            let nlo = lo.max((v - eps - va) / dz);
            let nhi = hi.min((v + eps - va) / dz);
            if nlo <= nhi {
                lo = nlo;
                hi = nhi;
                zl = z;
                open = true;
                return;
            }
            va += 0.5 * (lo + hi) * (zl - za);
            za = zl;
            nodes.push((za, va));
            lo = -BIG;
            hi = BIG;
            open = false;
        }
    };
    let mut v = 1.0f32;
    for &(_, z, a) in list {
        feed(z, v, &mut nodes);
        v *= 1.0 - a;
        feed(z, v, &mut nodes);
    }
    if open {
        let m = 0.5 * (lo + hi);
        nodes.push((zl, va + m * (zl - za)));
    }
    nodes
}

/// V'(z) of a node list just before (left) and after (right) depth z.
fn eval_nodes(nodes: &[(f32, f32)], z: f32, right: bool) -> f32 {
    let idx = nodes.partition_point(|&(nz, _)| nz < z || (right && nz == z));
    if idx == 0 {
        return 1.0;
    }
    let prev = nodes[idx - 1];
    if idx == nodes.len() {
        return prev.1;
    }
    let next = nodes[idx];
    if next.0 == prev.0 {
        return prev.1;
    }
    prev.1 + (next.1 - prev.1) * (z - prev.0) / (next.0 - prev.0)
}

/// Largest |V'(z) - V(z)| of a node list over a sorted list, just before
/// and just after each distinct depth (V steps once per distinct depth).
fn max_node_error(nodes: &[(f32, f32)], list: &[(u32, f32, f32)]) -> f32 {
    let (mut v, mut err, mut k) = (1.0f32, 0.0f32, 0);
    while k < list.len() {
        let z = list[k].1;
        err = err.max((eval_nodes(nodes, z, false) - v).abs());
        while k < list.len() && list[k].1 == z {
            v *= 1.0 - list[k].2;
            k += 1;
        }
        err = err.max((eval_nodes(nodes, z, true) - v).abs());
    }
    err
}

/// The GPU's stored visibility nodes against the texel records, the CPU
/// compression of the GPU's own sorted lists (same count, depths and V within
/// 1e-5) and the bound (|V' - V| <= eps + 1e-5 around every entry depth).
/// Returns (total nodes, max |V' - V|).
fn check_nodes(name: &str, raw: &DeepRaw, lists: &[Vec<(u32, f32, f32)>]) -> (u64, f32) {
    let gpu_nodes = raw.visibility_nodes();
    assert_eq!(gpu_nodes.len(), lists.len());
    let (mut total, mut max_err) = (0u64, 0.0f32);
    for (t, (nodes, list)) in gpu_nodes.iter().zip(lists).enumerate() {
        let tx = raw.texels[t];
        assert!(
            tx.nodes <= 2 * tx.count,
            "{name}: texel {t}: {} nodes for {} entries",
            tx.nodes,
            tx.count
        );
        assert_eq!(
            nodes.len(),
            tx.nodes as usize,
            "{name}: texel {t}: node run outside the arrays read"
        );
        total += nodes.len() as u64;
        let cpu = compress(list, deep::EPSILON);
        assert_eq!(
            nodes.len(),
            cpu.len(),
            "{name}: texel {t}: GPU {nodes:?} vs CPU {cpu:?}"
        );
        for (k, (g, c)) in nodes.iter().zip(&cpu).enumerate() {
            assert!(
                (g.0 - c.0).abs() <= 1e-5 * c.0.abs().max(1.0) && (g.1 - c.1).abs() <= 1e-5,
                "{name}: texel {t} node {k}: GPU {g:?} vs CPU {c:?}"
            );
        }
        assert!(
            nodes.windows(2).all(|p| p[0].0 <= p[1].0),
            "{name}: texel {t}: nodes out of depth order {nodes:?}"
        );
        let err = max_node_error(nodes, list);
        assert!(
            err <= deep::EPSILON + 1e-5,
            "{name}: texel {t}: stored |V'-V| = {err}"
        );
        max_err = max_err.max(err);
    }
    assert_eq!(
        raw.counters[deep::counter::NODES] as u64,
        total,
        "{name}: node counter vs stored nodes"
    );
    (total, max_err)
}

/// Checks the GPU's raw lists against the CPU model and the layout rules.
fn check_lists(
    name: &str,
    scene: &Scene,
    light: &Camera,
    raw: &DeepRaw,
    lists: &[Vec<(u32, f32, f32)>],
    opacity: f32,
) {
    let offset = light_depth_offset(scene, light);
    let cpu = cpu_lists(scene, light, offset);
    let (w, h) = (raw.map_width as usize, raw.map_height as usize);
    assert_eq!(lists.len(), w * h);
    let c = &raw.counters;
    assert_eq!(
        c[deep::counter::FILL_ERRORS],
        0,
        "{name}: fill slots outside their runs"
    );
    assert_eq!(
        c[deep::counter::OVERFLOW],
        0,
        "{name}: final frame overflowed"
    );
    let used = raw.ids.len();

    // Per texel: multiset of (id, depth) equals the CPU model's (up to
    // f32-ambiguous edges), sorted by (depth, id), links and counts agree.
    let (mut total, mut max_count, mut ambiguous_diffs, mut node_diffs, mut node_total) =
        (0u64, 0u32, 0, 0, 0u64);
    for t in 0..w * h {
        let tx = raw.texels[t];
        let gpu = &lists[t];
        assert_eq!(
            tx.count as usize,
            gpu.len(),
            "{name}: texel {t}: count {} but {} linked",
            tx.count,
            gpu.len()
        );
        assert_eq!(
            tx.fill, tx.count,
            "{name}: texel {t}: filled {} of {}",
            tx.fill, tx.count
        );
        total += tx.count as u64;
        max_count = max_count.max(tx.count);
        // Links: exactly `count` distinct in-range entries, then the terminator.
        if tx.count == 0 {
            assert_eq!(tx.head, NONE, "{name}: empty texel {t} has a head");
            assert_eq!(tx.nodes, 0);
        } else {
            let mut a = tx.head;
            let mut seen = HashSet::new();
            for k in 0..tx.count {
                assert!(
                    (a as usize) < used,
                    "{name}: texel {t}: link {k} = {a:#x} out of range"
                );
                assert!(seen.insert(a), "{name}: texel {t}: cycle at {a}");
                a = raw.next[a as usize];
            }
            assert_eq!(
                a, NONE,
                "{name}: texel {t}: list does not end after {} entries",
                tx.count
            );
        }
        // Order, alpha, transmittance.
        let mut v = 1.0f32;
        let mut a = tx.head;
        for (k, &(id, d, al)) in gpu.iter().enumerate() {
            if k > 0 {
                let (pid, pd, _) = gpu[k - 1];
                assert!(
                    pd < d || (pd == d && pid < id),
                    "{name}: texel {t} not sorted at {k}: {:?}",
                    &gpu[k - 1..=k]
                );
            }
            assert_eq!(al, opacity, "{name}: alpha");
            v *= 1.0 - al;
            assert!(
                (raw.trans[a as usize] - v).abs() <= 1e-6,
                "{name}: transmittance at texel {t} entry {k}"
            );
            a = raw.next[a as usize];
        }
        // Multiset against the CPU model.
        let by_id: HashMap<u32, f32> = gpu.iter().map(|e| (e.0, e.1)).collect();
        assert_eq!(
            by_id.len(),
            gpu.len(),
            "{name}: texel {t}: a sphere listed twice"
        );
        for e in &cpu[t] {
            match by_id.get(&e.id) {
                Some(&d) => {
                    let tol = 1e-4 * e.depth.abs().max(1.0);
                    assert!(
                        (d as f64 - e.depth).abs() <= tol,
                        "{name}: texel {t} sphere {}: depth {d} vs CPU {}",
                        e.id,
                        e.depth
                    );
                }
                None if e.ambiguous => ambiguous_diffs += 1,
                None => panic!(
                    "{name}: texel {t}: sphere {} missing (CPU model lists it)",
                    e.id
                ),
            }
        }
        let cpu_ids: HashSet<u32> = cpu[t].iter().map(|e| e.id).collect();
        for g in gpu {
            assert!(
                cpu_ids.contains(&g.0),
                "{name}: texel {t}: sphere {} listed but its disk misses the texel",
                g.0
            );
        }
        // Compressed visibility: the CPU replica's node count and bound.
        let nodes = compress(gpu, deep::EPSILON);
        node_total += tx.nodes as u64;
        if nodes.len() as u32 != tx.nodes {
            node_diffs += 1;
        }
        let mut v = 1.0f32;
        // V(z) steps once per distinct depth (equal depths step together).
        let mut k = 0;
        while k < gpu.len() {
            let z = gpu[k].1;
            let before = eval_nodes(&nodes, z, false);
            assert!(
                (before - v).abs() <= deep::EPSILON + 1e-5,
                "{name}: texel {t}: |V'-V| = {} before z = {z}",
                (before - v).abs()
            );
            while k < gpu.len() && gpu[k].1 == z {
                v *= 1.0 - gpu[k].2;
                k += 1;
            }
            let after = eval_nodes(&nodes, z, true);
            assert!(
                (after - v).abs() <= deep::EPSILON + 1e-5,
                "{name}: texel {t}: |V'-V| = {} after z = {z}",
                (after - v).abs()
            );
        }
    }
    assert_eq!(
        c[deep::counter::ENTRIES] as u64,
        total,
        "{name}: entry counter"
    );
    assert_eq!(
        c[deep::counter::MAX_COUNT],
        max_count,
        "{name}: max depth complexity"
    );
    assert_eq!(
        c[deep::counter::NODES] as u64,
        node_total,
        "{name}: node counter"
    );
    assert!(
        node_diffs * 100 <= (w * h),
        "{name}: node counts differ from the CPU replica on {node_diffs} texels"
    );
    let (stored_nodes, max_err) = check_nodes(name, raw, lists);
    eprintln!(
        "{name}: stored nodes {stored_nodes} for {total} entries ({:.3} nodes/entry), max |V'-V| {max_err:.6} \
         (eps {:.6})",
        stored_nodes as f64 / total.max(1) as f64,
        deep::EPSILON
    );

    // Chunk accounting: per tile ceil(entries / 64) contiguous chunks, the
    // pool counter is their sum, runs are disjoint and inside the pool, and
    // texel runs are the prefix sums of the tile's texel counts.
    let mut chunk_sum = 0u64;
    let mut runs = Vec::new();
    for ty in 0..raw.tiles_y as usize {
        for tx in 0..raw.tiles_x as usize {
            let tile = raw.tiles[ty * raw.tiles_x as usize + tx];
            assert_eq!(tile.flags & TILE_OVERFLOWED, 0);
            let mut entries = 0u32;
            for l in 0..64usize {
                let (x, y) = (tx * TILE as usize + l % 8, ty * TILE as usize + l / 8);
                if x >= w || y >= h {
                    continue;
                }
                let texel = raw.texels[y * w + x];
                if texel.count > 0 {
                    assert_eq!(
                        texel.head,
                        tile.first_chunk * CHUNK + entries,
                        "{name}: texel run not at its prefix sum"
                    );
                }
                entries += texel.count;
            }
            assert_eq!(tile.entries, entries, "{name}: tile ({tx},{ty}) entries");
            assert_eq!(
                tile.chunks,
                entries.div_ceil(CHUNK),
                "{name}: tile ({tx},{ty}) chunks"
            );
            if tile.chunks == 0 {
                assert_eq!(tile.first_chunk, NONE);
            } else {
                assert!(
                    tile.first_chunk + tile.chunks <= raw.chunk_capacity,
                    "{name}: tile run past the pool"
                );
                runs.push((tile.first_chunk, tile.chunks));
            }
            chunk_sum += tile.chunks as u64;
        }
    }
    assert_eq!(
        c[deep::counter::CHUNKS] as u64,
        chunk_sum,
        "{name}: pool counter is not the sum of tile chunks"
    );
    runs.sort_unstable();
    assert!(
        runs.windows(2).all(|p| p[0].0 + p[0].1 <= p[1].0),
        "{name}: tile chunk runs overlap"
    );
    eprintln!(
        "{name}: {total} entries in {} texels, {chunk_sum} chunks of {} (pool {}), max depth complexity {max_count}, \
         {node_total} compressed nodes (eps {:.4}), {ambiguous_diffs} f32-edge differences, {node_diffs} node-count differences",
        c[deep::counter::NONEMPTY],
        CHUNK,
        raw.chunk_capacity,
        deep::EPSILON
    );
}

/// Deterministic scene: random spheres plus two large ones whose footprints
/// go through the band jobs.
fn mixed_scene(n: usize, seed: u64) -> Scene {
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut rnd = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut spheres: Vec<Sphere> = (0..n)
        .map(|_| {
            let c = [
                (rnd() - 0.5) * 50.0,
                (rnd() - 0.5) * 50.0,
                (rnd() - 0.5) * 50.0,
            ]
            .map(|v| v as f32);
            sphere(c, (0.6 + 2.4 * rnd()) as f32)
        })
        .collect();
    spheres.push(sphere([8.0, -4.0, 3.0], 9.0));
    spheres.push(sphere([-12.0, 10.0, -6.0], 14.0));
    scene_of(spheres, "mixed")
}

/// Spheres in a line along the default light direction: every texel of a
/// small map lists all of them (more than the private-memory sort takes).
fn column_scene(n: usize) -> Scene {
    let step = 0.4 / 3f32.sqrt();
    let spheres = (0..n)
        .map(|k| sphere([k as f32 * step, k as f32 * step, k as f32 * step], 1.5))
        .collect();
    scene_of(spheres, "column")
}

fn guards_ok(name: &str, ctx: &Context, r: &Renderer) {
    let bad = r
        .inspect()
        .deep()
        .expect("deep")
        .damaged_guards(ctx)
        .expect("guards");
    assert!(
        bad.is_empty(),
        "{name}: guard words overwritten after {bad:?}"
    );
}

#[test]
fn lists_match_cpu_model() {
    let ctx = validated_context();
    for (name, scene, map, opacity) in [
        ("mixed-64", mixed_scene(300, 3), 64, 1.0f32),
        ("mixed-60-translucent", mixed_scene(400, 9), 60, 0.3),
        (
            "random-64",
            scene::procedural("random", 300, 5).expect("random"),
            64,
            0.7,
        ),
        // Deep texels (up to 100 entries): the private-memory sort.
        (
            "lattice-64",
            scene::procedural("lattice", 20_000, 1).expect("lattice"),
            64,
            0.5,
        ),
        // More than 256 entries: the sort in the buffers.
        ("column-16", column_scene(1100), 16, 0.01),
    ] {
        let s = deep_settings(&scene, 96, 80, map, opacity);
        let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
        let mut first = Vec::new();
        for frame in 0..2 {
            r.render_frame().expect("frame");
            guards_ok(name, &ctx, &r);
            let d = r.inspect().deep().expect("deep");
            let raw = d.read_raw(&ctx).expect("raw");
            let lists = d.read_lists(&ctx).expect("lists");
            if frame == 0 {
                check_lists(name, &scene, &d.light, &raw, &lists, opacity);
                let c = d.read_counters(&ctx).expect("counters");
                let st = r.inspect().deep_stats().expect("stats");
                let slots = st.chunk_capacity * CHUNK as u64;
                assert!(
                    st.bytes >= slots * deep::BYTES_PER_ENTRY,
                    "{name}: bytes {} leave out the node arrays",
                    st.bytes
                );
                assert_eq!(st.bytes, d.list_bytes());
                assert!(d.memory_bytes() > st.bytes);
                eprintln!(
                    "{name}: {} band jobs, stats {:?}",
                    c.band_jobs,
                    r.inspect().deep_stats()
                );
                if name.starts_with("mixed") {
                    assert!(
                        c.band_jobs > 0,
                        "{name}: the large spheres should have used band jobs"
                    );
                }
                if name.starts_with("lattice") {
                    let deep = c.max_depth_complexity;
                    assert!((65..=256).contains(&deep), "{name}: {c:?}");
                }
                if name.starts_with("column") {
                    assert!(c.max_depth_complexity > 256, "{name}: {c:?}");
                }
                first = lists;
            } else {
                // A second frame rebuilds exactly the same lists.
                assert!(lists == first, "{name}: the second frame's lists differ");
                let nodes = d.read_visibility_nodes(&ctx).expect("nodes");
                assert_eq!(nodes, raw.visibility_nodes());
                assert_eq!(nodes.len(), lists.len());
                assert_eq!(
                    raw.counters[deep::counter::ENTRIES],
                    lists.iter().map(|l| l.len() as u32).sum::<u32>()
                );
            }
        }
        let vg = r.inspect().read_vis_guard().expect("vis guard");
        assert!(
            vg.iter()
                .all(|&g| g == sphereshade::stages::raster::compute::GUARD_PATTERN)
        );
    }
    assert_no_validation_messages(&ctx);
}

#[test]
fn full_band_job_list_falls_back_to_per_sphere_loops() {
    let ctx = validated_context();
    let scene = mixed_scene(300, 3);
    let s = deep_settings(&scene, 96, 80, 64, 1.0);
    let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
    r.render_frame().expect("frame");
    let all_jobs = r.inspect().deep().unwrap().read_lists(&ctx).expect("lists");
    let jobs = r
        .inspect()
        .deep()
        .unwrap()
        .read_counters(&ctx)
        .unwrap()
        .band_jobs;
    assert!(jobs >= 2, "the large spheres should use band jobs");
    let shadow_jobs = r.inspect().read_shadow().expect("shadow");
    // Room for fewer bands than the first big sphere needs, then none.
    for limit in [jobs - 1, 1, 0] {
        r.inspect().deep().unwrap().set_job_limit(limit);
        r.render_frame().expect("frame");
        guards_ok("job-limit", &ctx, &r);
        let d = r.inspect().deep().unwrap();
        let c = d.read_counters(&ctx).unwrap();
        assert!(c.band_jobs <= limit);
        let raw = d.read_raw(&ctx).expect("raw");
        let lists = d.read_lists(&ctx).expect("lists");
        check_lists(
            &format!("job-limit-{limit}"),
            &scene,
            &d.light,
            &raw,
            &lists,
            1.0,
        );
        assert!(
            lists == all_jobs,
            "job limit {limit}: lists differ from the band-job version"
        );
        assert_eq!(r.inspect().read_shadow().unwrap(), shadow_jobs);
    }
    assert_no_validation_messages(&ctx);
}

/// Band jobs past the list where a sphere's footprint is larger than one
/// invocation may visit (BAND_INLINE_SAFE texels: lavapipe ends a loop
/// after 65,535 back-edges): the frame is drawn again with twice the
/// jobs. Four spheres over a 512^2 light map (64 bands each) and room for
/// 64 jobs: the same lists and shadows as with the default room, which is
/// then 256 (and smaller spheres' fallback, above, stays exact without).
#[test]
fn band_jobs_past_a_large_footprint_grow_and_match() {
    let ctx = validated_context();
    let scene = scene_of(screen_filling_spheres(), "screen-filling spheres");
    let render = |limit: Option<u32>| {
        let s = deep_settings(&scene, 128, 96, 512, 0.5);
        let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
        r.render_frame().expect("frame");
        if let Some(l) = limit {
            r.inspect().deep().unwrap().set_job_limit(l);
            r.render_frame().expect("frame");
        }
        guards_ok("large footprints", &ctx, &r);
        let d = r.inspect().deep().unwrap();
        let c = d.read_counters(&ctx).unwrap();
        assert!(!c.bands_full && c.fill_errors == 0, "{c:?}");
        (
            d.read_lists(&ctx).expect("lists"),
            r.inspect().read_shadow().expect("shadow"),
            d.job_limit(),
        )
    };
    let (la, sa, _) = render(None);
    let (lb, sb, limit) = render(Some(64));
    assert_eq!(limit, 256);
    assert!(la == lb, "the lists differ");
    assert!(sa == sb, "the shadows differ");
    assert_no_validation_messages(&ctx);
}

#[test]
fn overflow_grows_pool_and_matches_big_pool() {
    let ctx = validated_context();
    let scene = scene::procedural("random", 1500, 21).expect("random");
    let render = |pool: Option<u32>| {
        let mut s = deep_settings(&scene, 160, 120, 128, 1.0);
        s.deep.pool_chunks = pool;
        let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
        r.render_frame().expect("frame");
        guards_ok("overflow", &ctx, &r);
        let stats = r.inspect().deep_stats().expect("deep stats");
        let c = r.inspect().deep().unwrap().read_counters(&ctx).unwrap();
        assert_eq!(c.fill_errors, 0);
        assert!(!c.overflowed, "the final frame must fit");
        (
            r.inspect().read_color().expect("color"),
            r.inspect().read_shadow().expect("shadow"),
            stats,
        )
    };
    let (c1, s1, st1) = render(Some(1));
    let (c2, s2, st2) = render(Some(1 << 16));
    eprintln!("overflow: tiny pool {st1:?}\noverflow: big pool  {st2:?}");
    assert!(st1.overflowed, "a 1-chunk pool must report overflow");
    assert!(!st2.overflowed);
    assert!(
        st1.chunk_capacity >= st1.chunks_used && st1.chunk_capacity > 1,
        "pool not grown"
    );
    assert_eq!(st1.chunks_used, st2.chunks_used);
    assert_eq!(st1.entries, st2.entries);
    assert_eq!(s1, s2, "shadow buffer differs after growing the pool");
    assert_eq!(c1, c2, "colour differs after growing the pool");
    assert!(s1.iter().any(|&v| v < 0.5), "the scene should have shadows");
    assert_no_validation_messages(&ctx);
}

/// Exact key-light visibility at the reference's visible points and its ids.
fn reference_shadow(
    scene: &Scene,
    cam: &Camera,
    light: DVec3,
    opacity: f64,
) -> (Vec<Option<f64>>, Vec<u32>) {
    let (vis, img) = reference::shadow_image(&scene.spheres, cam, light, opacity);
    (vis, img.ids)
}

/// Renders with deep shadows and returns (percentage agreeing, compared
/// pixels): opaque = same hard mask, translucent = within 1/255.
fn deep_agreement(
    ctx: &Context,
    name: &str,
    scene: &Scene,
    w: u32,
    h: u32,
    opacity: f32,
) -> (f64, usize) {
    let s = deep_settings(scene, w, h, 512, opacity);
    let (cam, light) = (s.camera, s.light);
    let mut r = Renderer::new(ctx, scene, s).expect("renderer");
    r.render_frame().expect("frame");
    guards_ok(name, ctx, &r);
    let ids = ids_from_vis(&r.inspect().read_vis().expect("vis"));
    let shadow = r.inspect().read_shadow().expect("shadow");
    let (refs, ref_ids) = reference_shadow(scene, &cam, light, opacity as f64);
    let (mut compared, mut agree, mut shadowed) = (0usize, 0usize, 0usize);
    let mut diff = image::RgbImage::new(cam.width, cam.height);
    for i in 0..ids.len() {
        let Some(rv) = refs[i] else { continue };
        if ids[i] != Some(ref_ids[i]) {
            continue;
        }
        compared += 1;
        let g = shadow[i] as f64;
        let ok = if opacity >= 1.0 {
            (g < 0.5) == (rv < 0.5)
        } else {
            (g - rv).abs() <= 1.0 / 255.0
        };
        if rv < 0.5 {
            shadowed += 1;
        }
        let px = diff.get_pixel_mut(i as u32 % cam.width, i as u32 / cam.width);
        if ok {
            agree += 1;
            let l = (40.0 + 160.0 * rv) as u8;
            *px = image::Rgb([l, l, l]);
        } else {
            *px = if g < rv {
                image::Rgb([255, 0, 0])
            } else {
                image::Rgb([0, 255, 0])
            };
        }
    }
    let pct = 100.0 * agree as f64 / compared.max(1) as f64;
    let st = r.inspect().deep_stats().expect("stats");
    let d = r.inspect().deep().expect("deep");
    let (nodes, max_err) = check_nodes(
        name,
        &d.read_raw(ctx).expect("raw"),
        &d.read_lists(ctx).expect("lists"),
    );
    let max_nodes = d.read_counters(ctx).expect("counters").max_compressed_nodes;
    eprintln!(
        "{name}: opacity {opacity}: {nodes} visibility nodes (max {max_nodes} per texel) for {} entries: \
         {:.3} nodes/entry, max |V'-V| {max_err:.6}",
        st.entries,
        nodes as f64 / st.entries.max(1) as f64
    );
    eprintln!(
        "{name}: opacity {opacity}: {pct:.3}% of {compared} visible pixels agree ({shadowed} in shadow); deep: {} entries, \
         {} chunks, {} bytes vs fixed-layer {} bytes ({:.2}x)",
        st.entries,
        st.chunks_used,
        st.bytes,
        st.fixed_layer_bytes,
        st.fixed_layer_bytes as f64 / st.bytes.max(1) as f64
    );
    if pct < 99.95 {
        let p = out_dir().join(format!("{name}-deep-diff.png"));
        let _ = diff.save(&p);
        eprintln!("{name}: wrote {}", p.display());
    }
    (pct, compared)
}

fn assert_exact(ctx: &Context, name: &str, scene: &Scene) {
    let (pct, n) = deep_agreement(ctx, name, scene, 256, 200, 1.0);
    assert!(n > 5000, "{name}: too few comparable pixels ({n})");
    assert!(
        pct >= 99.9,
        "{name}: opaque deep shadows agree on only {pct:.3}%"
    );
    for opacity in [0.3f32, 0.7] {
        let (pct, _) = deep_agreement(ctx, &format!("{name}-a{opacity}"), scene, 256, 200, opacity);
        assert!(
            pct >= 99.0,
            "{name}: opacity {opacity}: only {pct:.3}% within 1/255"
        );
    }
}

#[test]
fn exact_shadows_1tii() {
    let ctx = validated_context();
    let s = load_data("1tii.pdb");
    assert_exact(&ctx, "deep-1tii", &s);
    assert_no_validation_messages(&ctx);
}

#[test]
fn exact_shadows_random() {
    let ctx = validated_context();
    let s = scene::procedural("random", 4000, 11).expect("random");
    assert_exact(&ctx, "deep-random", &s);
    assert_no_validation_messages(&ctx);
}

#[test]
fn a_lone_sphere_never_shadows_itself() {
    let ctx = validated_context();
    let scene = scene_of(vec![sphere([0.0, 0.0, 0.0], 5.0)], "lone");
    for opacity in [1.0f32, 0.5] {
        let mut r = Renderer::new(&ctx, &scene, deep_settings(&scene, 64, 64, 64, opacity))
            .expect("renderer");
        r.render_frame().expect("frame");
        let shadow = r.inspect().read_shadow().expect("shadow");
        assert!(
            shadow.iter().all(|&v| v == 1.0),
            "opacity {opacity}: a lone sphere shadows itself"
        );
        guards_ok("lone", &ctx, &r);
        let c = r.inspect().deep().unwrap().read_counters(&ctx).unwrap();
        assert!(
            c.band_jobs > 0,
            "a map-filling sphere should go through band jobs"
        );
    }
    assert_no_validation_messages(&ctx);
}

#[test]
fn lattice_stress_along_the_light() {
    let ctx = validated_context();
    let scene = scene::procedural("lattice", 50_000, 1).expect("lattice");
    // 512² is the benchmark's size; 256² keeps this test to seconds under validation.
    let map = 256u32;
    let mut s = deep_settings(&scene, 256, 256, map, 0.5);
    s.light = DVec3::new(0.0, 0.0, -1.0);
    let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
    let t0 = std::time::Instant::now();
    r.render_frame().expect("frame");
    let secs = t0.elapsed().as_secs_f64();
    guards_ok("lattice", &ctx, &r);
    let st = r.inspect().deep_stats().expect("stats");
    let c = r.inspect().deep().unwrap().read_counters(&ctx).unwrap();
    assert_eq!(c.fill_errors, 0);
    assert!(!c.overflowed);
    eprintln!(
        "lattice 50k, map {map}²: {} entries, {} chunks (capacity {}), max depth complexity {}, avg {:.1} per \
         non-empty texel, {} compressed nodes (max {}), {} band jobs; {} bytes vs fixed-layer {} bytes ({:.2}x); \
         retried: {}; frame {:.2} s under validation",
        st.entries,
        st.chunks_used,
        st.chunk_capacity,
        c.max_depth_complexity,
        st.entries as f64 / c.nonempty_texels.max(1) as f64,
        c.compressed_nodes,
        c.max_compressed_nodes,
        c.band_jobs,
        st.bytes,
        st.fixed_layer_bytes,
        st.fixed_layer_bytes as f64 / st.bytes.max(1) as f64,
        st.overflowed,
        secs
    );
    assert!(
        c.max_depth_complexity >= 37,
        "a 37-deep lattice seen along its axis"
    );
    // The top layer faces the light and nothing lies above it.
    let ids = ids_from_vis(&r.inspect().read_vis().unwrap());
    let shadow = r.inspect().read_shadow().unwrap();
    let visible = ids.iter().filter(|i| i.is_some()).count();
    assert!(visible > 0);
    assert!(
        ids.iter()
            .zip(&shadow)
            .all(|(i, &v)| i.is_none() || v == 1.0),
        "top layer must be lit"
    );
    assert_no_validation_messages(&ctx);
}

/// Light texels of 8,000 entries: more than lavapipe sorts in one
/// shader invocation (it stops every loop after 65,535 back-edges, and the
/// Shell sort and walk of such a run take more): the frame is refused with
/// one line naming the list length, not drawn with an unsorted list. On a
/// device without that limit the frame is drawn.
#[test]
fn a_list_longer_than_the_device_sorts_is_refused() {
    let ctx = validated_context();
    let scene = column_scene(8_000);
    let s = deep_settings(&scene, 64, 64, 32, 0.5);
    let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
    let got = r.render_frame();
    // (a CPU check of the lists: texels left unsorted or unlinked)
    let raw = r.inspect().deep().unwrap().read_raw(&ctx).unwrap();
    let c = r.inspect().deep().unwrap().read_counters(&ctx).unwrap();
    let broken = raw
        .texels
        .iter()
        .filter(|t| {
            let (n, b) = (t.count.min(t.fill) as usize, t.head as usize);
            n > 0
                && ((1..n).any(|i| raw.depth[b + i - 1] > raw.depth[b + i])
                    || raw.next[b + n - 1] != NONE)
        })
        .count();
    assert_eq!(c.sort_cut as usize, broken, "texels cut short");
    if ctx.props.device_type == ash::vk::PhysicalDeviceType::CPU {
        let msg = got
            .expect_err("an 8,000-entry list on lavapipe")
            .to_string();
        assert!(!msg.contains('\n'), "{msg}");
        assert!(msg.starts_with("deep shadow lists of up to "), "{msg}");
        let n: u32 = msg["deep shadow lists of up to ".len()..]
            .split(' ')
            .next()
            .and_then(|w| w.parse().ok())
            .expect("a length");
        assert!(n >= 7_900, "{msg}");
        assert!(broken > 0, "no list was cut short");
    } else {
        got.expect("frame");
        let c = r.inspect().deep().unwrap().read_counters(&ctx).unwrap();
        assert_eq!(c.sort_cut, 0);
    }
    drop(r);
    assert_no_validation_messages(&ctx);
}
