//! Typed fixes: the change a refused request can make, named as data ([`Fix`]), and how each
//! front end spells it ([`spelled`]). A leaf module: the library's errors name their fixes
//! through it without depending on the error-kind table of its parent module.

/// A change that can make a refused request work, named as data: the library's messages
/// write each [`Fix`] through [`std::fmt::Display`], which spells it in the terms of whoever
/// reads the message — by default the library's own (`LevelParams::rho`); the command line
/// and the Python module install their spelling (`--rho`, `rho=`) with [`spelled`] while
/// they format an error, so no front end rewrites message text.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Fix {
    /// Accept a regularized answer to an undetermined global least squares (a ridge on the
    /// singular directions, or CGLS's minimum-norm answer).
    RegularizedAnswer,
    /// Accept a regularized answer to a rank-deficient global least squares, or the local
    /// inversion, which cuts the unsupported directions.
    RegularizeOrLocal,
    /// The relative singular-value cut-off of the pseudo-inverse.
    Cutoff,
    /// Fixed levels: the fine level `N` chosen by the caller.
    FixedLevels,
    /// Automatic levels, chosen from the samples.
    AutoLevels,
    /// The oversampling rate `rho = m / P` of the automatic levels.
    Rho,
    /// The 1D refiner's samples per leaf `rho`.
    RefineRho,
    /// The single-scale global least squares (banded normal equations, then the FWT).
    MethodSingleScale,
    /// The local inversion.
    MethodLocal,
    /// The global sparse least squares on the multilevel kernel matrix.
    MethodGlobal,
    /// The dense SVD pseudo-inverse.
    MethodDense,
    /// Column-pivoted QR for the local blocks.
    SolverQr,
    /// Drop non-finite samples and count them instead of refusing the set.
    DropNonfinite,
    /// Set the image-plane parameter named (or the parameter itself, where a message names
    /// the parameter at fault).
    Set(Param),
    /// The image plane's default pixel estimate: a film per pixel chosen by SURE.
    PixelsAuto,
    /// The adaptive tree's matrix-free conjugate-gradient solve.
    SolverPcg,
}

/// The parameters of the image plane's jobs (`image::job`), as data, so a message
/// names the parameter at fault and each front end spells it (`--rho`, `rho=`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
#[non_exhaustive]
pub enum Param {
    /// Vanishing moments of the image basis.
    P,
    /// Samples per tensor function (the uniform fit) or per slot (the plan's tree).
    Rho,
    /// The relative ridge of the fit's normal equations.
    Ridge,
    /// The smoothing weight of the fit.
    Smoothing,
    /// The method (the fit, its local inversion, a film filter).
    Method,
    /// The fit's filter family (a front-end setting the image fit reads as asking for it).
    Family,
    /// The fit's levels (a front-end setting the image fit reads as asking for it).
    Levels,
    /// The pixel estimate of the uniform path.
    Pixels,
    /// The image resolution.
    Resolution,
    /// The tile size of the tiled fit.
    Tile,
    /// The halo of the tiled fit.
    Halo,
    /// Tiles fitted at once.
    Workers,
    /// A plan's state (folder) whose tree the final image is fitted on.
    State,
    /// The plan's own output without the residual (the fit's box pixels alone).
    NoResidual,
    /// Replace an output that exists.
    Overwrite,
    /// The sample budget of a plan.
    Budget,
    /// The adaptive tree's depth limit below the pixel.
    BelowPixel,
    /// The process's memory limit.
    MemoryLimit,
    /// The folder the tiled fit spills its band files into.
    Scratch,
    /// A plan's samples of its last round (to continue the plan).
    Samples,
    /// Samples per pixel of a sampled scene (the lab's `SamplingParams::spp`).
    Spp,
    /// The methods a lab comparison runs.
    Methods,
    /// The fine level `N` of a 1D basis `Psi(n, N)`.
    Fine,
    /// The share of a plan's round given to the pixels by their spread.
    PixelShare,
}

impl Param {
    /// Every parameter, so a front end can check that it spells each one.
    pub const ALL: [Param; 24] = [
        Param::P,
        Param::Rho,
        Param::Ridge,
        Param::Smoothing,
        Param::Method,
        Param::Family,
        Param::Levels,
        Param::Pixels,
        Param::Resolution,
        Param::Tile,
        Param::Halo,
        Param::Workers,
        Param::State,
        Param::NoResidual,
        Param::Overwrite,
        Param::Budget,
        Param::BelowPixel,
        Param::MemoryLimit,
        Param::Scratch,
        Param::Samples,
        Param::Spp,
        Param::Methods,
        Param::Fine,
        Param::PixelShare,
    ];

    /// The parameter in the library's terms (the field of `image::job::ImageParams`
    /// or of the call that takes it).
    pub fn in_library(self) -> &'static str {
        match self {
            Param::P => "ImageParams::fit.p",
            Param::Rho => "ImageParams::fit.rho",
            Param::Ridge => "ImageParams::fit.ridge",
            Param::Smoothing => "ImageParams::fit.smoothing",
            Param::Method => "ImageParams::method",
            Param::Family => "the filter family",
            Param::Levels => "the fit's levels",
            Param::Pixels => "ImageParams::pixels",
            Param::Resolution => "the ImagePlane",
            Param::Tile => "ImageParams::tiles.tile",
            Param::Halo => "ImageParams::tiles.halo",
            Param::Workers => "ImageParams::tiles.workers",
            Param::State => "the plan's state",
            Param::NoResidual => "PixelEstimate::FitOnly",
            Param::Overwrite => "overwrite",
            Param::Budget => "StopParams::budget",
            Param::BelowPixel => "QuadTreeParams::below_pixel",
            Param::MemoryLimit => "resources::set_memory_limit",
            Param::Scratch => "TiledParams::scratch",
            Param::Samples => "the rendered samples of the plan's positions",
            Param::Spp => "SamplingParams::spp",
            Param::Methods => "the methods compared",
            Param::Fine => "the basis's fine level N",
            Param::PixelShare => "GrowthParams::pixel_share",
        }
    }
}

impl Fix {
    /// Every fix, so a front end can check that it spells each one.
    pub const ALL: [Fix; 39] = [
        Fix::RegularizedAnswer,
        Fix::RegularizeOrLocal,
        Fix::Cutoff,
        Fix::FixedLevels,
        Fix::AutoLevels,
        Fix::Rho,
        Fix::RefineRho,
        Fix::MethodSingleScale,
        Fix::MethodLocal,
        Fix::MethodGlobal,
        Fix::MethodDense,
        Fix::SolverQr,
        Fix::DropNonfinite,
        Fix::PixelsAuto,
        Fix::Set(Param::ALL[0]),
        Fix::Set(Param::ALL[1]),
        Fix::Set(Param::ALL[2]),
        Fix::Set(Param::ALL[3]),
        Fix::Set(Param::ALL[4]),
        Fix::Set(Param::ALL[5]),
        Fix::Set(Param::ALL[6]),
        Fix::Set(Param::ALL[7]),
        Fix::Set(Param::ALL[8]),
        Fix::Set(Param::ALL[9]),
        Fix::Set(Param::ALL[10]),
        Fix::Set(Param::ALL[11]),
        Fix::Set(Param::ALL[12]),
        Fix::Set(Param::ALL[13]),
        Fix::Set(Param::ALL[14]),
        Fix::Set(Param::ALL[15]),
        Fix::Set(Param::ALL[16]),
        Fix::Set(Param::ALL[17]),
        Fix::Set(Param::ALL[18]),
        Fix::Set(Param::ALL[19]),
        Fix::Set(Param::ALL[20]),
        Fix::Set(Param::ALL[21]),
        Fix::Set(Param::ALL[22]),
        Fix::Set(Param::ALL[23]),
        Fix::SolverPcg,
    ];

    /// The fix in the library's terms: the parameter to set and its value.
    pub fn in_library(self) -> &'static str {
        match self {
            Fix::RegularizedAnswer => {
                "GlobalLsParams::rank_policy = RankPolicy::Regularize (ridge \
                 GlobalLsParams::ridge, e.g. 1e-10) or GlobalLsParams::method = \
                 GlobalMethod::Cgls"
            }
            Fix::RegularizeOrLocal => {
                "GlobalLsParams::rank_policy = RankPolicy::Regularize, or the local inversion"
            }
            Fix::Cutoff => "`cutoff` of LocalInversionParams or Method::Dense",
            Fix::FixedLevels => "Levels::Fixed { fine, .. }",
            Fix::AutoLevels => "Levels::Auto",
            Fix::Rho => "LevelParams::rho",
            Fix::RefineRho => "RefineParams::rho",
            Fix::MethodSingleScale => "Method::SingleScale",
            Fix::MethodLocal => "Method::Local",
            Fix::MethodGlobal => "Method::Global",
            Fix::MethodDense => "Method::Dense",
            Fix::SolverQr => "Solver::Qr",
            Fix::DropNonfinite => "NonFinitePolicy::Drop",
            Fix::Set(param) => param.in_library(),
            Fix::PixelsAuto => "UniformEstimate::Auto",
            Fix::SolverPcg => "TreeSolver::Pcg",
        }
    }
}

/// How a front end spells each [`Fix`] ([`Fix::in_library`] is the library's).
pub type Spelling = fn(Fix) -> &'static str;

thread_local! {
    /// The spelling [`Fix`]'s `Display` uses on this thread.
    static SPELLING: std::cell::Cell<Spelling> = const { std::cell::Cell::new(Fix::in_library) };
}

/// Runs `format` (typically `|| error.to_string()`) with every [`Fix`] written in
/// `spelling`, on this thread only; the previous spelling is restored afterwards, also when
/// `format` panics.
pub fn spelled<R>(spelling: Spelling, format: impl FnOnce() -> R) -> R {
    struct Restore(Spelling);
    impl Drop for Restore {
        fn drop(&mut self) {
            SPELLING.with(|s| s.set(self.0));
        }
    }
    let _restore = Restore(SPELLING.with(|s| s.replace(spelling)));
    format()
}

impl std::fmt::Display for Fix {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(SPELLING.with(|s| s.get())(*self))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn upper(fix: Fix) -> &'static str {
        match fix {
            Fix::Rho => "RHO",
            _ => "OTHER",
        }
    }

    /// A fix reads in the library's terms, in the spelling given inside [`spelled`], and in
    /// the library's terms again afterwards, also after a panic inside.
    #[test]
    fn spelling_is_scoped() {
        assert_eq!(Fix::Rho.to_string(), "LevelParams::rho");
        assert_eq!(spelled(upper, || Fix::Rho.to_string()), "RHO");
        assert_eq!(Fix::Rho.to_string(), "LevelParams::rho");
        let nested = spelled(upper, || {
            let inner = spelled(Fix::in_library, || Fix::Rho.to_string());
            (inner, Fix::Rho.to_string())
        });
        assert_eq!(nested, ("LevelParams::rho".to_string(), "RHO".to_string()));
        let panicked = std::panic::catch_unwind(|| spelled(upper, || panic!("inside")));
        assert!(panicked.is_err());
        assert_eq!(Fix::Rho.to_string(), "LevelParams::rho");
    }

    /// Errors that advise a fix write it through the spelling.
    #[test]
    fn errors_spell_their_fixes() {
        let e = crate::solve::SolveError::TooLarge {
            rows: 10,
            cols: 5,
            limit: 4,
        };
        let library = e.to_string();
        assert!(
            library.contains("Method::Global or Method::SingleScale"),
            "{library}"
        );
        let other = spelled(upper, || e.to_string());
        assert!(other.contains("(OTHER or OTHER)"), "{other}");
        for fix in Fix::ALL {
            assert!(!fix.in_library().is_empty());
        }
    }
}
