//! Small, deterministic learners fitted at run time: a multinomial logistic regression
//! ([`softmax_regression`]), gradient-boosted trees ([`boosted_trees`]) and stratified
//! cross-validation ([`cross_validation`]). citymesh uses the regression to fit a new
//! roof-classifier head on the embeddings of the buildings whose `roof:shape` is tagged
//! (docs/extensions.md section 3), and the trees for the roof
//! prior learned from an area's tags (`crate::roof_prior`).

pub mod boosted_trees;
pub mod cross_validation;
pub mod softmax_regression;

pub use boosted_trees::{BoostOptions, BoostedTrees};
pub use cross_validation::{CrossValidation, Example, cross_validate, cross_validate_with};
pub use softmax_regression::{FitOptions, SoftmaxRegression};
