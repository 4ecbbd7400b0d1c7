//! The library's messages speak of parameters (`LevelParams::rho`, `Method::Local`); on the
//! command line the same advice must name the flags that set them. [`in_flags`] rewrites the
//! library spellings a message can contain into this command line's flags, so every hint a
//! user reads names something they can type.

/// Library spellings and what the command line says instead, longest first (a phrase is
/// replaced before the shorter names inside it). A parameter with no flag is rewritten into
/// the command-line way to get the same effect.
const FLAG_SPELLINGS: &[(&str, &str)] = &[
    (
        "GlobalLsParams::rank_policy = RankPolicy::Regularize (ridge GlobalLsParams::ridge, \
         e.g. 1e-10) or GlobalLsParams::method = GlobalMethod::Cgls",
        "--method single (it sets the undetermined directions to zero and reports them)",
    ),
    (
        "GlobalLsParams::rank_policy = RankPolicy::Regularize, or the local inversion",
        "--method single, or the local inversion",
    ),
    (
        "`cutoff` of LocalInversionParams or Method::Dense",
        "--cutoff",
    ),
    ("Levels::Fixed { fine, .. }", "--levels n..N"),
    ("Levels::Auto", "--levels auto"),
    ("LevelParams::rho", "--rho"),
    ("RefineParams::rho", "--rho"),
    ("LevelParams::coarse_samples", "--coarse-samples"),
    ("Method::SingleScale", "--method single"),
    ("Method::Local", "--method local"),
    ("Method::Global", "--method global"),
    ("Method::Dense", "--method dense"),
    ("Solver::Qr", "--solver qr"),
    ("Solver::Svd", "--solver svd"),
    ("NonFinitePolicy::Drop", "--drop-nonfinite"),
];

/// `message` with every library spelling of [`FLAG_SPELLINGS`] replaced by its flag.
pub fn in_flags(message: &str) -> String {
    FLAG_SPELLINGS
        .iter()
        .fold(message.to_string(), |m, (library, flag)| {
            m.replace(library, flag)
        })
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
        }
        .to_string();
        let rank = rkwave::solve::SolveError::RankDeficient {
            column: 2,
            pivot: 1e-14,
            threshold: 1e-10,
            column_samples: 1,
        }
        .to_string();
        for m in [undersampled, rank] {
            let cli = in_flags(&m);
            assert!(!cli.contains("::"), "{cli}");
            assert!(cli.contains("--method"), "{cli}");
        }
        assert_eq!(in_flags("raise LevelParams::rho"), "raise --rho");
    }
}
