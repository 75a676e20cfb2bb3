//! Which entries of a packed parameter vector a fit holds, and how: free, fixed, or tied to another.

/// How one entry of a packed parameter vector is filled from the free ones.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Pin {
    /// Fitted.
    Free,
    /// Held at a value.
    Fixed(f64),
    /// `scale * entry[to] + offset`, `to` a free entry.
    Tied { to: usize, scale: f64, offset: f64 },
}

/// A rule for every entry of a packed vector.
#[derive(Debug, Clone, PartialEq)]
pub struct Pins(pub Vec<Pin>);

impl Pins {
    /// Every entry of a vector of `n` fitted.
    pub fn free(n: usize) -> Self {
        Self(vec![Pin::Free; n])
    }

    /// The free entries of `full`, in order.
    pub fn reduce(&self, full: &[f64]) -> Vec<f64> {
        self.0
            .iter()
            .zip(full)
            .filter(|(p, _)| **p == Pin::Free)
            .map(|(_, v)| *v)
            .collect()
    }

    /// The whole vector from its free entries `reduced`.
    pub fn expand(&self, reduced: &[f64]) -> Vec<f64> {
        let mut free = reduced.iter();
        let mut full: Vec<f64> = self
            .0
            .iter()
            .map(|p| match p {
                Pin::Free => free.next().copied().unwrap_or(f64::NAN),
                Pin::Fixed(v) => *v,
                Pin::Tied { .. } => f64::NAN,
            })
            .collect();
        for (i, p) in self.0.iter().enumerate() {
            if let Pin::Tied { to, scale, offset } = *p {
                full[i] = scale * full[to] + offset;
            }
        }
        full
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Free entries come back in order; a tie follows its free entry; a fixed one keeps its value.
    #[test]
    fn pins_expand_what_they_reduce() {
        let pins = Pins(vec![
            Pin::Free,
            Pin::Fixed(1.0),
            Pin::Free,
            Pin::Tied {
                to: 2,
                scale: -1.0,
                offset: 0.5,
            },
        ]);
        let full = [3.0, 9.0, 2.0, 7.0];
        let r = pins.reduce(&full);
        assert_eq!(r, vec![3.0, 2.0]);
        assert_eq!(pins.expand(&r), vec![3.0, 1.0, 2.0, -1.5]);
        assert_eq!(Pins::free(2).expand(&[4.0, 5.0]), vec![4.0, 5.0]);
    }
}
