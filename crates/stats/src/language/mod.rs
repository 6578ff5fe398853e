//! The language-generalization analysis of the DexJoCo paper (appendix A): which
//! password a policy enters for each instruction, and whether that depends on the
//! instruction at all.
//!
//! `input` reads a study (the reference evaluator's episode folders, or a tidy CSV/JSON);
//! `report` analyses it (distribution, precision, chi-square, NMI, Jensen-Shannon,
//! verdict).

mod input;
mod report;

pub use input::{
    EXAMPLE_MARKER, Instruction, LanguageInput, MANIFEST_FILE, NONE_OUTPUT, Trial, infer_expected,
};
pub use report::{JsPair, LanguageOptions, LanguageReport, Precision, format_p};

#[cfg(test)]
mod tests {
    use super::input::infer_expected;
    use super::report::output_order;

    #[test]
    fn expected_answers_are_inferred() {
        assert_eq!(infer_expected("1").as_deref(), Some("1"));
        assert_eq!(infer_expected("two").as_deref(), Some("2"));
        assert_eq!(infer_expected("1+1").as_deref(), Some("2"));
        assert_eq!(infer_expected("2 + 2").as_deref(), Some("4"));
        assert_eq!(infer_expected("one plus one").as_deref(), Some("2"));
        assert_eq!(
            infer_expected("password_one_plus_one").as_deref(),
            Some("2")
        );
        assert_eq!(infer_expected("banana"), None);
        assert_eq!(infer_expected(""), None);
    }

    #[test]
    fn outputs_are_ordered_numbers_then_words_then_none() {
        let mut v: Vec<String> = ["none", "12", "3", "x", "1"].map(String::from).to_vec();
        v.sort_by(output_order);
        assert_eq!(v, ["1", "3", "12", "x", "none"]);
    }
}
