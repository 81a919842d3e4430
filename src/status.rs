//! How a solve ended: the one status every method, batch and binding reports.
//! Below every solver and the errors (an error carries one): it knows none
//! of them. Its parsing from a name sits with the solution.
//!
//! Also the [`named_enum!`] macro that declares it and the other enums the API
//! names (`Scheme`, `IkEnding`): each variant's snake_case name and its doc
//! comment, the one source of the Python enums' members and their docs.

/// An enum of unit variants the API names: each variant's snake_case name and
/// its description (its doc comment) are kept with it, so that the bindings
/// generate their enums from here rather than mirror them by hand.
pub trait NamedEnum: Copy + 'static {
    /// What the enum is (its doc comment).
    const DOC: &'static str;
    /// Every variant, in the order of the declaration.
    const VARIANTS: &'static [Self];
    /// The snake_case name used by the Python API and in messages.
    fn name(self) -> &'static str;
    /// What the variant means (its doc comment, one paragraph).
    fn description(self) -> String;
}

/// Declares an enum of unit variants, each `Variant => "name"` after its doc
/// comment, with its `ALL`, `name()` and [`NamedEnum`].
macro_rules! named_enum {
    (
        $(#[doc = $doc:literal])*
        #[derive($($derive:ident),*)]
        $vis:vis enum $Enum:ident {
            $(
                $(#[doc = $variant_doc:literal])*
                $Variant:ident => $name:literal,
            )*
        }
    ) => {
        $(#[doc = $doc])*
        #[derive($($derive),*)]
        $vis enum $Enum {
            $($(#[doc = $variant_doc])* $Variant,)*
        }

        impl $Enum {
            /// Every variant, in the order of the declaration.
            pub const ALL: [$Enum; [$($name),*].len()] = [$($Enum::$Variant),*];

            /// The snake_case name used by the Python API and in messages.
            pub fn name(self) -> &'static str {
                match self {
                    $($Enum::$Variant => $name,)*
                }
            }
        }

        impl $crate::status::NamedEnum for $Enum {
            const DOC: &'static str = concat!($($doc, "\n"),*);
            const VARIANTS: &'static [Self] = &$Enum::ALL;
            fn name(self) -> &'static str {
                $Enum::name(self)
            }
            fn description(self) -> String {
                let lines: &[&str] = match self {
                    $($Enum::$Variant => &[$($variant_doc),*],)*
                };
                lines.iter().map(|l| l.trim()).collect::<Vec<_>>().join(" ")
            }
        }
    };
}
pub(crate) use named_enum;

named_enum! {
    /// How a solve ended. Only `converged` is an answer; every other ending
    /// carries the best state reached, its residual and a message.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum Status {
        /// The relative residual is below `residual_tol`, the state is finite
        /// and every element turns within what the scheme resolves.
        Converged => "converged",
        /// The methods stalled before the iteration budget ran out: the line
        /// search or the load continuation (below `min_continuation_step`)
        /// could not progress, or the paper's method ended above its tolerance.
        NotConverged => "not_converged",
        /// The iteration budget (`max_iterations`) ran out before convergence.
        IterationLimit => "iteration_limit",
        /// Accuracy on demand stopped at its largest `n` with the error
        /// estimate above the tolerance (the state is a converged equilibrium
        /// at that `n`).
        ToleranceNotMet => "tolerance_not_met",
        /// The discrete rod cannot follow the shape; solve with more elements.
        /// Either an equilibrium whose elements turn by more than 1 rad (a
        /// coiled rod folds onto itself), or, not attempted, a held point
        /// beyond the discrete rod's reach.
        Underresolved => "underresolved",
        /// The state or the residual is not finite (an overflow).
        NumericalError => "numerical_error",
        /// Not attempted: the scene has no well-defined answer (a held point at
        /// full reach, whose reaction is indeterminate or unbounded).
        Indeterminate => "indeterminate",
    }
}
