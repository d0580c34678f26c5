//! Destroy-on-error for Vulkan objects under construction: a constructor
//! that makes several objects wraps each in a [`Guard`], so an early `?`
//! destroys what was already made (no leaks reported when, say, the fifth
//! buffer is over the device's limit), and `keep()` hands the object over
//! once everything succeeded.

use super::Context;
use std::ops::{Deref, DerefMut};

/// Objects that are destroyed explicitly with the context that made them.
pub trait Destroy {
    fn destroy_with(&mut self, ctx: &Context);
}

impl<T: Destroy> Destroy for Option<T> {
    fn destroy_with(&mut self, ctx: &Context) {
        if let Some(v) = self {
            v.destroy_with(ctx);
        }
    }
}

impl<T: Destroy> Destroy for Vec<T> {
    fn destroy_with(&mut self, ctx: &Context) {
        for v in self {
            v.destroy_with(ctx);
        }
    }
}

impl<T: Destroy, const N: usize> Destroy for [T; N] {
    fn destroy_with(&mut self, ctx: &Context) {
        for v in self {
            v.destroy_with(ctx);
        }
    }
}

/// Implements [`Destroy`] through the type's own `destroy(ctx)` method.
#[macro_export]
macro_rules! impl_destroy {
    ($($t:ty),* $(,)?) => {
        $(impl $crate::vk::guard::Destroy for $t {
            fn destroy_with(&mut self, ctx: &$crate::vk::Context) {
                self.destroy(ctx);
            }
        })*
    };
}

impl_destroy!(super::Buffer, super::ComputePipeline, super::Profiler);

/// Owns `T` until [`Guard::keep`]; destroys it if dropped before that.
pub struct Guard<'c, T: Destroy> {
    ctx: &'c Context,
    value: Option<T>,
}

impl<'c, T: Destroy> Guard<'c, T> {
    pub fn new(ctx: &'c Context, value: T) -> Self {
        Guard {
            ctx,
            value: Some(value),
        }
    }

    /// Construction succeeded: the caller owns (and destroys) the value.
    pub fn keep(mut self) -> T {
        match self.value.take() {
            Some(v) => v,
            None => unreachable!("a guard holds its value until keep() consumes it"),
        }
    }
}

impl<T: Destroy> Deref for Guard<'_, T> {
    type Target = T;
    fn deref(&self) -> &T {
        match &self.value {
            Some(v) => v,
            None => unreachable!("a guard holds its value until keep() consumes it"),
        }
    }
}

impl<T: Destroy> DerefMut for Guard<'_, T> {
    fn deref_mut(&mut self) -> &mut T {
        match &mut self.value {
            Some(v) => v,
            None => unreachable!("a guard holds its value until keep() consumes it"),
        }
    }
}

impl<T: Destroy> Drop for Guard<'_, T> {
    fn drop(&mut self) {
        if let Some(v) = &mut self.value {
            v.destroy_with(self.ctx);
        }
    }
}

impl Context {
    /// Wraps a freshly made object so an error before `keep()` destroys it.
    pub fn guard<T: Destroy>(&self, value: T) -> Guard<'_, T> {
        Guard::new(self, value)
    }
}
