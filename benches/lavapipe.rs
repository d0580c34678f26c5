//! `cargo bench --bench lavapipe`: times glsl/test/micro.comp's modes (one per
//! fact in docs/LAVAPIPE.md) with timestamps on the chosen device, 1920x1080
//! invocations each, median of 5 runs after a warm-up, and prints a table.

use sphereshade::passes::spirv;
use sphereshade::vk::Recorder;
use sphereshade::vk::descriptors::DescriptorArena;
use sphereshade::vk::pipeline::{PipelineDesc, image_wo, ro, texel, uniform, wo};
use sphereshade::vk::{Buffer, ComputePipeline, Context, ContextOptions, Grid, Profiler};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    n: u32,
    taps: u32,
    flag: u32,
    pad: u32,
}

const CASES: &[(u32, u32, &str)] = &[
    (19, 16, "empty: every invocation returns at once"),
    (18, 16, "address arithmetic only, no loads (16 taps)"),
    (
        20,
        16,
        "uniform texel buffer fetch (r32ui), per-lane address (16 taps)",
    ),
    (
        21,
        16,
        "integer division and remainder by a push constant (16 taps)",
    ),
    (22, 16, "the same through a float reciprocal (16 taps)"),
    (
        23,
        16,
        "16 sin steps, straight-line, under a push-constant if no lane takes",
    ),
    (24, 16, "the same, taken by every lane"),
    (
        25,
        16,
        "the same under a specialization-constant if no lane takes",
    ),
    (26, 16, "the same as a one-trip loop that no lane enters"),
    (27, 16, "the one-trip loop, entered by 1 lane in 8"),
    (
        0,
        16,
        "storage buffer vec4 load, per-lane address (16 taps)",
    ),
    (
        1,
        16,
        "storage buffer float load, per-lane address (16 taps)",
    ),
    (
        2,
        16,
        "storage buffer vec4 load, same address in all lanes (16 taps)",
    ),
    (
        3,
        16,
        "uniform texel buffer fetch (rgba32f), per-lane address (16 taps)",
    ),
    (
        14,
        16,
        "storage buffer vec4 load, neighbouring addresses (16 taps)",
    ),
    (
        16,
        16,
        "storage buffer float load, neighbouring addresses (16 taps)",
    ),
    (
        15,
        16,
        "uniform texel buffer fetch (rgba32f), neighbouring addresses (16 taps)",
    ),
    (4, 16, "shared memory vec4 load, per-lane address (16 taps)"),
    (5, 16, "uniform buffer vec4 load, per-lane index (16 taps)"),
    (
        6,
        16,
        "if/else on a push constant, all lanes one way (16 sin iterations)",
    ),
    (7, 16, "the same if/else on a specialization constant"),
    (
        17,
        16,
        "if/else on a per-lane condition (half the lanes each way)",
    ),
    (8, 16, "1 lane in 8 loops 128 sin iterations, 7 loop none"),
    (
        9,
        16,
        "every lane loops 16 sin iterations (same total work)",
    ),
    (
        10,
        16,
        "all work (32 iterations) in the first half of the workgroups",
    ),
    (
        11,
        16,
        "the same work in every other workgroup (interleaved)",
    ),
    (
        28,
        16,
        "storage buffer vec4 store, per-lane address (16 taps)",
    ),
    (
        29,
        16,
        "storage texel buffer (rgba32f) imageStore, per-lane address (16 taps)",
    ),
    (
        30,
        16,
        "storage buffer uint store, per-lane address (16 taps)",
    ),
    (
        31,
        16,
        "storage texel buffer (r32ui) imageStore, per-lane address (16 taps)",
    ),
    (
        32,
        16,
        "storage buffer vec4 store, neighbouring addresses (16 taps)",
    ),
    (
        33,
        16,
        "storage texel buffer (rgba32f) imageStore, neighbouring addresses (16 taps)",
    ),
    (12, 16, "fp16 multiply-add chain (128 steps)"),
    (13, 16, "fp32 multiply-add chain (128 steps)"),
];

fn main() {
    let ctx = Context::new(&ContextOptions::default()).expect("Vulkan context");
    let n: u32 = 1920 * 1080;
    let elements: u32 = 1 << 21; // the shader masks addresses to 2^21
    let mut src = Buffer::storage(&ctx, "micro src", elements as u64 * 16).expect("src");
    let data: Vec<f32> = (0..elements * 4).map(|k| (k % 97) as f32 * 0.01).collect();
    src.upload(&ctx, 0, bytemuck::cast_slice(&data))
        .expect("upload");
    let mut dst = Buffer::storage(&ctx, "micro dst", n as u64 * 16).expect("dst");
    let mut table = Buffer::new(
        &ctx,
        "micro table",
        64 * 16,
        ash::vk::BufferUsageFlags::UNIFORM_BUFFER,
        gpu_allocator::MemoryLocation::GpuOnly,
    )
    .expect("table");
    table
        .upload(&ctx, 0, bytemuck::cast_slice(&data[..256]))
        .expect("table");
    let mut prof = Profiler::new(&ctx, 4).expect("profiler");
    let mut arena = DescriptorArena::default();
    println!("device: {} ({})", ctx.info.name, ctx.info.driver);
    println!("| mode | case | ms (median of 5) |\n|---:|---|---:|");
    for &(mode, taps, what) in CASES {
        let mut pipe = ComputePipeline::new(
            &ctx,
            &PipelineDesc {
                name: "micro",
                shader: spirv::MICRO_COMP,
                bindings: &[
                    ro("Src"),
                    wo("Dst"),
                    texel("srcTex", ash::vk::Format::R32G32B32A32_SFLOAT),
                    uniform("GlobalsBlock"),
                    texel("srcWordTex", ash::vk::Format::R32_UINT),
                    image_wo("dstImg", ash::vk::Format::R32G32B32A32_SFLOAT),
                    image_wo("dstWordImg", ash::vk::Format::R32_UINT),
                    wo("DstWords"),
                ],
                push_size: 16,
                local_size: 64,
                constants: &[mode, 1],
                scene: 0,
            },
        )
        .expect("pipeline");
        let mut times = Vec::new();
        for run in 0..6 {
            let ms = ctx
                .one_shot("micro", |cmd| {
                    prof.begin_frame(&ctx, cmd);
                    let mut rec = Recorder::new(&ctx, cmd, &mut arena, Some(&mut prof));
                    rec.pass("micro", |p| {
                        p.dispatch(
                            &pipe,
                            &Push {
                                n,
                                taps,
                                flag: 1,
                                pad: 0,
                            },
                            Grid::Invocations(n as u64),
                            &[
                                ("Src", &src),
                                ("Dst", &dst),
                                ("srcTex", &src),
                                ("GlobalsBlock", &table),
                                ("srcWordTex", &src),
                                ("dstImg", &dst),
                                ("dstWordImg", &dst),
                                ("DstWords", &dst),
                            ],
                        );
                        Ok(())
                    })
                })
                .and_then(|_| prof.results(&ctx))
                .expect("run")
                .passes[0]
                .1;
            arena.reset(&ctx).expect("arena");
            if run > 0 {
                times.push(ms);
            }
        }
        times.sort_by(f64::total_cmp);
        println!("| {mode} | {what} | {:.1} |", times[times.len() / 2]);
        pipe.destroy(&ctx);
    }
    arena.destroy(&ctx);
    prof.destroy(&ctx);
    for b in [&mut src, &mut dst, &mut table] {
        b.destroy(&ctx);
    }
}
