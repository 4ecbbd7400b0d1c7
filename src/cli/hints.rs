//! The library's messages speak of parameters (`LevelParams::rho`, `Method::Local`) through
//! typed [`Fix`] values; on the command line the same advice names the flags that set them.
//! [`flag`] spells each fix as this command line's flag, and [`in_flags`] formats a message
//! with that spelling, so every hint a user reads names something they can type. No message
//! text is inspected or rewritten.

use rkwave::error::{spelled, Fix, Param};

/// `fix` as the command line spells it: the flag that sets the parameter, or the
/// command-line way to get the same effect where the parameter has no flag.
pub fn flag(fix: Fix) -> &'static str {
    match fix {
        Fix::RegularizedAnswer => {
            "--method single (it sets the undetermined directions to zero and reports them)"
        }
        Fix::RegularizeOrLocal => "--method single, or the local inversion",
        Fix::Cutoff => "--cutoff",
        Fix::FixedLevels => "--levels n..N",
        Fix::AutoLevels => "--levels auto",
        Fix::Rho | Fix::RefineRho => "--rho",
        Fix::MethodSingleScale => "--method single",
        Fix::MethodLocal => "--method local",
        Fix::MethodGlobal => "--method global",
        Fix::MethodDense => "--method dense",
        Fix::SolverQr => "--solver qr",
        Fix::DropNonfinite => "--drop-nonfinite",
        Fix::PixelsAuto => "--pixels auto",
        Fix::SolverPcg => "--solver pcg",
        Fix::Set(param) => match param {
            Param::P => "--p",
            Param::Rho => "--rho",
            Param::Ridge => "--ridge",
            Param::Smoothing => "--smoothing",
            Param::Method => "--method",
            Param::Family => "--family",
            Param::Levels => "--levels",
            Param::Pixels => "--pixels",
            Param::Resolution => "--resolution",
            Param::Tile => "--tile",
            Param::Halo => "--halo",
            Param::Workers => "--workers",
            Param::State => "--state",
            Param::NoResidual => "--no-residual",
            Param::Overwrite => "--force",
            Param::Budget => "--budget",
            Param::BelowPixel => "--below-pixel",
            Param::MemoryLimit => "--memory-limit",
            Param::Scratch => "--scratch",
            Param::Samples => "--samples",
            Param::Spp => "--spp",
            Param::Methods => "--methods",
            Param::Fine => "--fine",
            Param::PixelShare => "--pixel-share",
            _ => param.in_library(),
        },
        _ => fix.in_library(),
    }
}

/// The text `format` makes (e.g. `|| error.to_string()`) with every [`Fix`] spelled as a flag.
pub fn in_flags<R>(format: impl FnOnce() -> R) -> R {
    spelled(flag, format)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The library's own messages come out with flags and no Rust paths.
    #[test]
    fn library_hints_become_flags() {
        let undersampled = rkwave::solve::SolveError::Undersampled {
            samples: 3,
            functions: 8,
        };
        let rank = rkwave::solve::SolveError::RankDeficient {
            column: 2,
            pivot: 1e-14,
            threshold: 1e-10,
            column_samples: 1,
        };
        for e in [undersampled, rank] {
            let library = e.to_string();
            let cli = in_flags(|| e.to_string());
            assert!(library.contains("RankPolicy::Regularize"), "{library}");
            assert!(!cli.contains("::"), "{cli}");
            assert!(cli.contains("--method"), "{cli}");
            // The spelling holds only inside `in_flags`.
            assert_eq!(e.to_string(), library);
        }
    }

    /// Every fix has a flag spelling: none falls back to the library's Rust path.
    #[test]
    fn every_fix_is_spelled_as_a_flag() {
        for fix in Fix::ALL {
            let text = flag(fix);
            assert!(text.starts_with("--"), "{fix:?}: {text}");
            assert!(!text.contains("::"), "{fix:?}: {text}");
        }
    }
}
