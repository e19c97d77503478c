//! The shipped plants and their default scenarios, built into the binary so that `demo` runs on
//! built-in defaults from any folder. The files in `plants/` and `scenarios/` are the same text.

/// (plant file name, plant JSON, scenario file name, scenario JSON)
pub const BUILTIN: &[(&str, &str, &str, &str)] = &[
    (
        "bouc_wen_piezo.json",
        include_str!("../../plants/bouc_wen_piezo.json"),
        "seed_1dof.json",
        include_str!("../../scenarios/seed_1dof.json"),
    ),
    (
        "prandtl_ishlinskii_piezo.json",
        include_str!("../../plants/prandtl_ishlinskii_piezo.json"),
        "seed_1dof.json",
        include_str!("../../scenarios/seed_1dof.json"),
    ),
    (
        "prandtl_ishlinskii_asymmetric.json",
        include_str!("../../plants/prandtl_ishlinskii_asymmetric.json"),
        "seed_1dof.json",
        include_str!("../../scenarios/seed_1dof.json"),
    ),
    (
        "creep_piezo.json",
        include_str!("../../plants/creep_piezo.json"),
        "creep_steps.json",
        include_str!("../../scenarios/creep_steps.json"),
    ),
    (
        "piezo_2dof.json",
        include_str!("../../plants/piezo_2dof.json"),
        "seed_2dof.json",
        include_str!("../../scenarios/seed_2dof.json"),
    ),
    (
        "bouc_wen_benchmark.json",
        include_str!("../../plants/bouc_wen_benchmark.json"),
        "boucwen_multisine.json",
        include_str!("../../scenarios/boucwen_multisine.json"),
    ),
    (
        "hidden_creep_piezo.json",
        include_str!("../../plants/hidden_creep_piezo.json"),
        "hidden_effect_1khz.json",
        include_str!("../../scenarios/hidden_effect_1khz.json"),
    ),
];
