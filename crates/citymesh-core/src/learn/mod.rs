//! Small, deterministic learners fitted at run time: a multinomial logistic regression
//! ([`softmax_regression`]) and its stratified cross-validation ([`cross_validation`]). citymesh
//! uses them to fit a new roof-classifier head on the embeddings of the buildings whose
//! `roof:shape` is tagged (docs/method.md, "Adapting the classifier to the user's imagery").

pub mod cross_validation;
pub mod softmax_regression;

pub use cross_validation::{CrossValidation, Example, cross_validate};
pub use softmax_regression::{FitOptions, SoftmaxRegression};
