//! The adaptive image engine on the command line (issue 13, item 5): `compare --adaptive`
//! adds the adaptive rows (text, JSON, table, one figure per scene).

mod common;

/// `compare --adaptive` on a small scene: the JSON carries the adaptive comparison (the
/// adaptive wavelet within the budget, the film filters on the adaptive samples beside the
/// stratified ones), one adaptive run per noise level (the noisy one on noisy samples, its
/// noise test's cut-offs in the notes), the table and the figures are written, and nothing is
/// replaced without --force.
#[test]
fn compare_adaptive_adds_the_adaptive_rows() {
    let dir = common::scratch("cmpad", "rows");
    let out = dir.join("cmp");
    let args = [
        "compare",
        "--scene",
        "slanted_edge",
        "--resolution",
        "32x32",
        "--spp",
        "4",
        "--noise",
        "0,0.05",
        "--methods",
        "box",
        "--adaptive",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ];
    let run = common::rkwave(&args);
    assert!(run.status.success(), "{}", common::text(&run));
    let json: serde_json::Value =
        serde_json::from_slice(&run.stdout).expect("one JSON object on stdout");
    assert_eq!(json["comparisons"].as_array().map(Vec::len), Some(2));
    let adaptive = &json["adaptive"][0];
    assert_eq!(adaptive["scene"], "slanted_edge");
    let samples = adaptive["adaptive"]["samples"].as_u64().unwrap();
    assert!(samples > 0 && samples <= 4 * 32 * 32, "{samples}");
    let rows = adaptive["rows"].as_array().unwrap();
    assert_eq!(rows[0]["method"], "adaptive wavelet");
    assert_eq!(rows[1]["method"], "adaptive wavelet, fit only");
    // the default output is the residual-corrected image, its pixels counted
    let pixels = &adaptive["adaptive"]["pixels"];
    assert_eq!(pixels["estimate"], "residual_clamped");
    assert!(pixels["corrected"].as_u64().unwrap() <= pixels["sampled"].as_u64().unwrap());
    for from in ["stratified", "adaptive"] {
        for film in ["box", "triangle", "gaussian", "mitchell", "lanczos"] {
            assert!(
                rows.iter()
                    .any(|r| r["samples_from"] == from && r["method"] == film),
                "{film} on {from} samples missing"
            );
        }
    }
    let gain = adaptive["gain_db"].as_f64().unwrap();
    let best = adaptive["best_uniform_film"][1].as_f64().unwrap();
    let psnr = rows[0]["metrics"]["psnr"].as_f64().unwrap();
    assert!((psnr - best - gain).abs() < 1e-9);
    let noisy = &json["adaptive"][1];
    assert_eq!(json["adaptive"].as_array().map(Vec::len), Some(2));
    assert_eq!(adaptive["noise"], 0.0);
    assert_eq!(noisy["noise"], 0.05);
    let last = noisy["adaptive"]["rounds"]
        .as_array()
        .unwrap()
        .last()
        .unwrap();
    let sigma = last["noise"]["sigma"].as_f64().unwrap();
    assert!((0.03..0.08).contains(&sigma), "estimated sigma {sigma}");
    assert!(noisy["rows"].as_array().unwrap().len() == rows.len());
    assert!(json["adaptive_notes"].as_array().unwrap().iter().any(|n| n
        .as_str()
        .is_some_and(|n| n.contains("noise 0.05") && n.contains("not significant"))));
    for f in [
        "compare_adaptive.md",
        "slanted_edge_adaptive.png",
        "slanted_edge_noise0.05_adaptive.png",
    ] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    let table = std::fs::read_to_string(out.join("compare_adaptive.md")).unwrap();
    assert!(
        table.contains("| slanted_edge | 4 | 0 | adaptive |"),
        "{table}"
    );
    assert!(
        table.contains("| slanted_edge | 4 | 0.05 | adaptive |"),
        "{table}"
    );
    let again = common::user_error(&args);
    assert!(again.contains("--force"), "{again}");
}

/// `image --adaptive --adaptive-params JSON`: a field that is not a parameter, malformed JSON
/// and an out-of-range value are refused with exit code 2, naming the way out; nothing is run.
#[test]
fn adaptive_params_overrides_are_checked() {
    let dir = common::scratch("cmpad", "params");
    let out = dir.join("o.png");
    let out = out.to_str().unwrap();
    let run = |json: &str| {
        common::user_error(&[
            "image",
            "--scene",
            "slanted_edge",
            "--resolution",
            "16x16",
            "--adaptive",
            "--out",
            out,
            "--adaptive-params",
            json,
        ])
    };
    let e = run(r#"{"thetta": 0.3}"#);
    assert!(e.contains("no parameter named \"thetta\""), "{e}");
    let e = run("{theta: 0.3");
    assert!(e.contains("--adaptive-params"), "{e}");
    let e = run(r#"{"theta": 2.0}"#);
    assert!(e.contains("theta = 2"), "{e}");
    let e = run(r#"{"residual_z": -1.0}"#);
    assert!(e.contains("residual_z = -1"), "{e}");
    let e = run(r#"{"pixels": "sharpest"}"#);
    assert!(e.contains("residual_clamped"), "{e}");
}

/// `plan --false-alarm` sets the noise test of a new plan; the state keeps it, a later call
/// with another rate is refused naming the parameter, and a rate outside `[0, 1)` is refused.
#[test]
fn plan_takes_the_false_alarm_rate() {
    let dir = common::scratch("cmpad", "plan_false_alarm");
    let state = dir.join("state");
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let bad = common::user_error(&[
        "plan",
        "--state",
        &s(&state),
        "--resolution",
        "16x16",
        "--budget",
        "1024",
        "--false-alarm",
        "1.5",
        "--out",
        &s(&dir.join("bad.npy")),
    ]);
    assert!(
        bad.contains("false_alarm") || bad.contains("false-alarm"),
        "{bad}"
    );
    let run = common::rkwave(&[
        "plan",
        "--state",
        &s(&state),
        "--resolution",
        "16x16",
        "--budget",
        "1024",
        "--false-alarm",
        "0",
        "--out",
        &s(&dir.join("next0.npy")),
        "--json",
    ]);
    assert!(run.status.success(), "{}", common::text(&run));
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(state.join("state.json")).unwrap()).unwrap();
    assert_eq!(saved["params"]["false_alarm"], 0.0, "{saved}");
    let other = common::user_error(&[
        "plan",
        "--state",
        &s(&state),
        "--false-alarm",
        "0.05",
        "--samples",
        &s(&dir.join("next0.npy")),
        "--out",
        &s(&dir.join("next1.npy")),
    ]);
    assert!(other.contains("false_alarm"), "{other}");
}

/// `rkwave image --scene slanted_edge --resolution 16x16 --spp 4 --adaptive --force --out OUT`
/// with `extra` flags, which must succeed.
fn slanted_edge_16(out: &std::path::Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "image",
        "--scene",
        "slanted_edge",
        "--resolution",
        "16x16",
        "--spp",
        "4",
        "--adaptive",
        "--force",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(extra);
    let o = common::rkwave(&args);
    assert!(o.status.success(), "{}", common::text(&o));
    o
}

/// `image --adaptive --no-residual`: the output is the fit's box pixels (the first row equals
/// the fit-only row, nothing corrected); without it the corrections are counted in the JSON
/// and in the text's notes.
#[test]
fn image_adaptive_no_residual() {
    let dir = common::scratch("cmpad", "no_residual");
    let out = dir.join("o.png");
    let run = |extra: &[&str]| slanted_edge_16(&out, extra);
    let json = |o: std::process::Output| -> serde_json::Value {
        serde_json::from_slice(&o.stdout).expect("one JSON object")
    };
    let plain = json(run(&["--json", "--no-residual"]));
    assert_eq!(plain["adaptive"]["pixels"]["estimate"], "fit_only");
    assert_eq!(plain["adaptive"]["pixels"]["corrected"], 0);
    assert_eq!(
        plain["rows"][0]["metrics"]["psnr"],
        plain["rows"][1]["metrics"]["psnr"]
    );
    let corrected = json(run(&["--json"]));
    let c = &corrected["adaptive"]["pixels"];
    assert_eq!(c["estimate"], "residual_clamped");
    assert!(c["corrected"].as_u64().unwrap() > 0, "{c}");
    let text = common::text(&run(&[]));
    assert!(
        text.contains(&format!("mean residual in {} of", c["corrected"])),
        "{text}"
    );
}

/// `image --adaptive --solver`: every round's fit is made by the solver asked for (named in
/// each round's JSON; PCG may hand a stalled round to the direct solve, `pcg->direct`), the
/// iterative ones print their iterations per round, and an unknown solver is refused naming
/// the choices. Every round run to the solver's tolerance, the iterative solvers grow the
/// direct solve's tree (the same functions and samples in every round) and give its image:
///
/// - Schwarz CG (to 1e-10) to 1e-6 dB of PSNR;
/// - PCG (to relative residual `rho = 1e-6` of the equilibrated normal equations
///   `A^T A y = A^T f`, `A = K D`) within what `rho` allows: the fit at the samples moves by
///   `||A dy|| <= rho sqrt(kappa) ||f||` (`kappa` the condition of `A^T A`, which PCG
///   estimates and reports), so with values in `[0, 1]` the RMS change is at most
///   `rho sqrt(kappa)`; a pixel is a mean of the fit, so its RMS change is the same up to the
///   samples' quadrature of the image (a factor 2 allowed); and
///   `PSNR = -20 log10(RMSE)` moves by at most `(20 / ln 10) dRMSE / RMSE`.
#[test]
fn image_adaptive_solver_choice() {
    let dir = common::scratch("cmpad", "solver");
    let out = dir.join("o.png");
    // every round to the solver's tolerance (the default stops the rounds' CG at 1e-2, and
    // a round's tree then depends on where CG stopped)
    let run = |solver: &str, json: bool| {
        let extra = [
            "--solver",
            solver,
            "--adaptive-params",
            r#"{"round_tolerance": null}"#,
            "--json",
        ];
        slanted_edge_16(&out, &extra[..if json { 5 } else { 4 }])
    };
    let mut psnr = Vec::new();
    let mut trees = Vec::new();
    let (mut rho, mut kappa) = (0.0f64, 0.0f64);
    for solver in ["direct", "pcg", "schwarz"] {
        let v: serde_json::Value =
            serde_json::from_slice(&run(solver, true).stdout).expect("one JSON object");
        let rounds = v["adaptive"]["rounds"].as_array().unwrap();
        assert!(!rounds.is_empty());
        for r in rounds {
            let used = r["fit"]["solver"].as_str().unwrap();
            assert!(used.starts_with(solver), "{solver}: round fitted by {used}");
            if solver == "pcg" {
                assert_eq!(r["fit"]["converged"], true, "{}", r["fit"]);
                rho = rho.max(r["fit"]["relative_residual"].as_f64().unwrap());
                kappa = kappa.max(r["fit"]["condition"].as_f64().unwrap());
            }
        }
        let tree: Vec<(u64, u64)> = rounds
            .iter()
            .map(|r| {
                (
                    r["functions"].as_u64().unwrap(),
                    r["samples"].as_u64().unwrap(),
                )
            })
            .collect();
        trees.push(tree);
        psnr.push(v["rows"][1]["metrics"]["psnr"].as_f64().unwrap());
    }
    assert!(trees[1] == trees[0] && trees[2] == trees[0], "{trees:?}");
    assert!((psnr[0] - psnr[2]).abs() < 1e-6, "{psnr:?}");
    assert!(
        rho > 0.0 && rho <= 1e-6 && kappa >= 1.0,
        "rho {rho:e}, kappa {kappa}"
    );
    let rmse = 10f64.powf(-psnr[0] / 20.0);
    let allowed = 20.0 / std::f64::consts::LN_10 * 2.0 * rho * kappa.sqrt() / rmse;
    assert!(
        (psnr[1] - psnr[0]).abs() <= allowed,
        "PCG {} dB against direct {} dB: more than {allowed:e} dB apart (rho {rho:e}, \
         kappa {kappa})",
        psnr[1],
        psnr[0]
    );
    let text = common::text(&run("schwarz", false));
    assert!(
        text.contains("CG per round:") && text.contains("schwarz"),
        "{text}"
    );
    // by default the rounds stop early and the final fit is continued, which is printed
    let text = common::text(&slanted_edge_16(&out, &["--solver", "pcg"]));
    assert!(text.contains("final fit continued to"), "{text}");
    let e = common::user_error(&["image", "--adaptive", "--solver", "lu"]);
    assert!(e.contains("direct, pcg, schwarz"), "{e}");
}
