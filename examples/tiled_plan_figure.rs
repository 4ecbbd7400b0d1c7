//! The tiled plan's figures (docs/measurements/scale-out.md): the plan on tiles, or the
//! untiled plan, at `SIZE` (WxH), 8 spp, on a built-in scene with Gaussian noise 0.05 (a
//! renderer's Monte Carlo noise in miniature), to its stop. Prints the wall and CPU seconds
//! (user + system, every thread) spent in rkwave (rendering the scene excluded), the samples
//! taken, CPU µs a sample and PSNR / relMSE against the scene's box truth (4² strata a
//! pixel), and the peak resident set over the phases.
//!
//! `cargo run --release --example tiled_plan_figure -- [SIZE] [TILE] [SCENE] [untiled|rebuild]`
//! (defaults `512x512`, 128, `shapes`; `untiled` runs the untiled plan instead; the tiled plan
//! keeps each tile's PCG diagonal between rounds up to 512 MiB, `rebuild` sums it afresh
//! every round as the command line does). Every round's report (with where its time went)
//! and the final image's times go to stderr as JSON, with the heap in every phase (`heap
//! {...}` lines: bytes live at the phase's end and the most live during it, counted by this
//! example's allocator, with the resident set now and its most during the phase and glibc's
//! arenas: held, free inside them, and blocks mapped on their own). The peak resident set over
//! the phases is printed last (`/usr/bin/time -v`'s counts only the last phase: the kernel's
//! peak is reset at each phase).

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rkwave::image::adaptive::{ImageOracle, NoisyOracle, SamplePositions, SceneOracle};
use rkwave::image::job::tiled_plan::{TiledPlanOptions, TiledPlanStart};
use rkwave::image::job::{PlanBudget, PlanFinal, PlanOptions, PlanStart};
use rkwave::image::metrics::compare;
use rkwave::image::scene::Scene;
use rkwave::image::truth::box_truth;
use rkwave::image::{DroppedSamples, ImagePlane, ImageSamples};

/// The bound on the tiles' kept PCG diagonals (0.6 MB a window of 128²: 80 MB at 1080p,
/// 300 MB at 4K in tiles of 128).
const KEPT_DIAGONALS: u64 = 512 << 20;

/// The system allocator, counting the bytes live and their most since the last
/// [`heap_phase`] (relaxed atomics: a count, not a synchronisation).
struct CountingAlloc;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
/// The resident set's most over the phases so far (bytes; the kernel's own peak is reset
/// every phase, so `/usr/bin/time -v`'s is the last phase's only).
static RSS_PEAK: AtomicUsize = AtomicUsize::new(0);

fn grew(by: usize) {
    let now = LIVE.fetch_add(by, Ordering::Relaxed) + by;
    PEAK.fetch_max(now, Ordering::Relaxed);
}

// SAFETY: every call is the system allocator's own; the counts only observe sizes.
unsafe impl GlobalAlloc for CountingAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
            grew(new_size);
        }
        p
    }
}

#[global_allocator]
static HEAP: CountingAlloc = CountingAlloc;

/// The resident set now and its most since the last [`reset_peak_rss`], in bytes
/// (`/proc/self/status`'s `VmRSS` and `VmHWM`; zeros where that file does not exist).
fn rss() -> (u64, u64) {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find_map(|l| l.strip_prefix(name))
            .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            .map_or(0, |kb| kb * 1024)
    };
    (field("VmRSS:"), field("VmHWM:"))
}

/// Starts the next phase's resident peak from now (Linux: `5` to `/proc/self/clear_refs`
/// resets `VmHWM` to the present resident set; elsewhere the peak is the process's).
fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// Bytes glibc's arenas hold (mapped by `brk` or their own heaps), of those free inside
/// them, and in blocks mapped on their own (`mallinfo2`: `arena`, `fordblks`, `hblkhd`).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn arenas() -> (usize, usize, usize) {
    // SAFETY: `mallinfo2` only reads the allocator's counters.
    let m = unsafe { libc::mallinfo2() };
    (m.arena, m.fordblks, m.hblkhd)
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn arenas() -> (usize, usize, usize) {
    (0, 0, 0)
}

/// Prints the heap's bytes live now and the most live since the last phase, the resident
/// set now and its most since the last phase, and glibc's arenas (GB, 10^9), then starts the
/// next phase's peaks from now.
fn heap_phase(phase: &str) {
    let live = LIVE.load(Ordering::Relaxed);
    let peak = PEAK.swap(live, Ordering::Relaxed);
    let (rss_now, rss_peak) = rss();
    reset_peak_rss();
    RSS_PEAK.fetch_max(rss_peak as usize, Ordering::Relaxed);
    let (arena, free, mapped) = arenas();
    let gb = |b: u64| b as f64 / 1e9;
    eprintln!(
        "heap {{\"phase\": \"{phase}\", \"live_gb\": {:.3}, \"peak_gb\": {:.3}, \
         \"rss_gb\": {:.3}, \"rss_peak_gb\": {:.3}, \"arenas_gb\": {:.3}, \
         \"arenas_free_gb\": {:.3}, \"mapped_gb\": {:.3}}}",
        gb(live as u64),
        gb(peak as u64),
        gb(rss_now),
        gb(rss_peak),
        gb(arena as u64),
        gb(free as u64),
        gb(mapped as u64),
    );
}

/// This process's CPU seconds so far, user and system, every thread (`getrusage`; zeros
/// where it is not available). The figure's "rkwave CPU" is its growth over the plan's calls
/// only (rendering the scene excluded), so idle pool threads spinning count as rkwave's.
#[cfg(unix)]
fn cpu_seconds() -> (f64, f64) {
    // SAFETY: `getrusage` only writes the struct handed to it.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } != 0 {
        return (0.0, 0.0);
    }
    let s = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    (s(u.ru_utime), s(u.ru_stime))
}

#[cfg(not(unix))]
fn cpu_seconds() -> (f64, f64) {
    (0.0, 0.0)
}

/// Wall and CPU (user, system) seconds spent in rkwave's calls, summed.
#[derive(Default)]
struct Spent {
    wall: f64,
    user: f64,
    system: f64,
}

impl Spent {
    /// Runs `f`, adding its wall and CPU seconds.
    fn time<T>(&mut self, f: impl FnOnce() -> T) -> T {
        let (u0, s0) = cpu_seconds();
        let t = Instant::now();
        let out = f();
        self.wall += t.elapsed().as_secs_f64();
        let (u1, s1) = cpu_seconds();
        self.user += u1 - u0;
        self.system += s1 - s0;
        out
    }
}

/// FNV-1a over the bits of `values` in order: equal digests for the same numbers in the same
/// order, so two builds' positions and images are compared bit for bit.
fn bits_digest<'a>(values: impl Iterator<Item = &'a f64>) -> u64 {
    values.fold(0xcbf2_9ce4_8422_2325, |h, v| {
        (h ^ v.to_bits()).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// The samples so far: positions in the order handed out and every channel's values.
struct Rendered {
    xs: Vec<f64>,
    ys: Vec<f64>,
    values: Vec<Vec<f64>>,
}

impl Rendered {
    fn render(&mut self, oracle: &dyn ImageOracle, next: &SamplePositions) {
        let mut buf = vec![0.0; oracle.channels()];
        // exactly: a vector grown by doubling holds up to twice the samples (2.6 GB more at
        // 3840x2160)
        self.xs.reserve_exact(next.len());
        self.ys.reserve_exact(next.len());
        for c in &mut self.values {
            c.reserve_exact(next.len());
        }
        for (&x, &y) in next.xs.iter().zip(&next.ys) {
            oracle.sample(x, y, &mut buf);
            self.xs.push(x);
            self.ys.push(y);
            for (c, v) in self.values.iter_mut().zip(&buf) {
                c.push(*v);
            }
        }
    }
    /// The samples so far, moved out (no second copy while the plan works on them).
    fn take(&mut self, plane: ImagePlane) -> Result<ImageSamples, Box<dyn std::error::Error>> {
        Ok(ImageSamples::new(
            plane,
            std::mem::take(&mut self.xs),
            std::mem::take(&mut self.ys),
            self.values.iter_mut().map(std::mem::take).collect(),
        )?)
    }
    /// The samples back from [`Rendered::take`] (moved, no copy).
    fn restore(&mut self, samples: ImageSamples) {
        (self.xs, self.ys, self.values) = samples.into_parts();
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let size = args.first().map_or("512x512", String::as_str);
    let tile: usize = args.get(1).map_or(Ok(128), |s| s.parse())?;
    let scene_name = args.get(2).map_or("shapes", String::as_str);
    let untiled = args.get(3).is_some_and(|a| a == "untiled");
    // `rebuild`: every round sums each tile's PCG diagonal afresh, as the command line does
    let rebuild = args.get(3).is_some_and(|a| a == "rebuild");
    let (w, h) = size.split_once('x').ok_or("SIZE is WxH, e.g. 512x512")?;
    let plane = ImagePlane::new(w.parse()?, h.parse()?)?;
    let scene = Scene::from_file(Scene::builtin_dir().join(format!("{scene_name}.json")))?;
    let clean = SceneOracle {
        scene: &scene,
        plane,
    };
    let oracle = NoisyOracle {
        inner: &clean,
        sigma: 0.05,
        seed: 7,
    };
    let options = PlanOptions {
        budget: Some(PlanBudget::PerPixel(8)),
        ..PlanOptions::default()
    };
    let mut r = Rendered {
        xs: vec![],
        ys: vec![],
        values: vec![vec![]; oracle.channels()],
    };
    let mut spent = Spent::default();
    let image = if untiled {
        let (mut state, base) = spent.time(|| PlanStart::new(plane, &options)?.run())?;
        r.render(&oracle, &base);
        drop(base);
        loop {
            let samples = r.take(plane)?;
            let step =
                spent.time(|| state.advance_imaging(&samples, DroppedSamples::default(), false))?;
            r.restore(samples);
            if step.stop.is_some() {
                break;
            }
            r.render(&oracle, &step.next);
        }
        let samples = r.take(plane)?;
        let image = spent
            .time(|| PlanFinal::of(&state, false).run(&samples, DroppedSamples::default(), None))?
            .image;
        r.restore(samples);
        image
    } else {
        let tiles = TiledPlanOptions {
            tile,
            halo: None,
            workers: None,
        };
        let (mut state, base) =
            spent.time(|| TiledPlanStart::new(plane, &options, &tiles)?.run(oracle.channels()))?;
        if !rebuild {
            state.keep_diagonals(Some(KEPT_DIAGONALS));
        }
        heap_phase("start");
        r.render(&oracle, &base);
        drop(base);
        heap_phase("render base");
        loop {
            let samples = r.take(plane)?;
            let step = spent.time(|| state.advance(&samples))?;
            eprintln!("{}", serde_json::to_string(&step)?);
            r.restore(samples);
            heap_phase(&format!("round {}", state.round()));
            if step.stop.is_some() {
                break;
            }
            r.render(&oracle, &step.next);
            drop(step);
            heap_phase("render");
        }
        let starts: usize = state
            .tiles
            .iter()
            .filter_map(|t| t.start.as_ref())
            .map(|s| s.nonzero())
            .sum();
        eprintln!("tiles' carried starts: {starts} entries");
        let samples = r.take(plane)?;
        let last = spent.time(|| state.final_image(&samples, None))?;
        heap_phase("final image");
        eprintln!("final {}", serde_json::to_string(&last.times)?);
        r.restore(samples);
        last.image
    };
    let m = compare(&image, &box_truth(&scene, plane, 4));
    heap_phase("truth and metrics");
    let samples = r.xs.len();
    let cpu = spent.user + spent.system;
    println!(
        "{size} {} {scene_name}: rkwave {:.2} s wall, CPU {cpu:.2} s (user {:.2}, system {:.2}), \
         {samples} samples, {:.2} µs CPU a sample, PSNR {:.3} dB, relMSE {:.4e}, \
         positions {:016x}, image {:016x}",
        if untiled {
            "untiled".to_string()
        } else if rebuild {
            format!("tile {tile}, diagonals rebuilt")
        } else {
            format!("tile {tile}, diagonals kept")
        },
        spent.wall,
        spent.user,
        spent.system,
        cpu * 1e6 / samples.max(1) as f64,
        m.psnr,
        m.rel_mse,
        bits_digest(r.xs.iter().chain(&r.ys)),
        bits_digest(image.channels.iter().flatten()),
    );
    println!(
        "peak resident set over the phases: {} kB",
        RSS_PEAK.load(Ordering::Relaxed) / 1024
    );
    Ok(())
}
