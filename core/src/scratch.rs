//! Whether a stage of the step grew one of its reusable buffers.
//!
//! A warm step allocates nothing: its buffers keep their capacity from tick
//! to tick. A buffer that grows has allocated, and the step reports the
//! stages that grew one. Each stage lists its buffers once, in a method
//! that returns their [`Capacities`]; it takes them before its work and
//! compares after it.

/// A reusable buffer, by its capacity.
pub(crate) trait Scratch {
    /// The elements it holds room for.
    fn room(&self) -> usize;
}

impl<T> Scratch for Vec<T> {
    fn room(&self) -> usize {
        self.capacity()
    }
}

/// Two buffers that trade contents during a stage count as one, by their
/// summed capacity: the trade alone is no growth.
impl<A: Scratch, B: Scratch> Scratch for (&A, &B) {
    fn room(&self) -> usize {
        self.0.room() + self.1.room()
    }
}

/// The capacities of a stage's buffers at one moment.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Capacities<const N: usize>([usize; N]);

impl<const N: usize> Capacities<N> {
    /// The buffers' capacities now.
    pub(crate) fn of(buffers: [&dyn Scratch; N]) -> Self {
        Capacities(buffers.map(|b| b.room()))
    }

    /// Whether a buffer's capacity changed since `before`: the stage grew
    /// it.
    pub(crate) fn grew_since(&self, before: &Capacities<N>) -> bool {
        self != before
    }

    /// How many buffers' capacities changed since `before`.
    pub(crate) fn growths_since(&self, before: &Capacities<N>) -> u32 {
        self.0.iter().zip(&before.0).filter(|(a, b)| a != b).count() as u32
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_push_past_the_capacity_is_growth_and_a_trade_is_not() {
        let mut a: Vec<u32> = Vec::with_capacity(2);
        let mut b: Vec<u32> = Vec::with_capacity(8);
        let before = Capacities::of([&(&a, &b)]);
        std::mem::swap(&mut a, &mut b);
        assert!(!Capacities::of([&(&a, &b)]).grew_since(&before));
        let before = Capacities::of([&a, &b]);
        b.extend([1, 2]);
        assert!(!Capacities::of([&a, &b]).grew_since(&before));
        b.push(3);
        assert!(Capacities::of([&a, &b]).grew_since(&before));
        a.extend([1, 2, 3, 4, 5, 6, 7, 8, 9]);
        assert_eq!(Capacities::of([&a, &b]).growths_since(&before), 2);
    }
}
