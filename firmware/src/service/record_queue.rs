//! The readout task's queue of closed cycles to the main loop, whose losses keep their place.
//!
//! The readout task runs in an interrupt and cannot wait: when the queue is full, the record it
//! just closed is dropped. That record is *newer* than every record still queued, so the gap
//! it leaves belongs after them. The producer counts the drops and the next record that fits
//! carries the count ([`Tagged::lost_before`]); the main loop hands the service the loss right
//! before that record (`Service::pass`), so the stream's sequence gap stands exactly where the
//! lost cycles were and the records before it keep their sequence numbers (a host dates frames
//! by them). Drops after the last queued record are reported with the next one.

use heapless::spsc::Producer;

/// A record and the records dropped right before it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tagged<T> {
    /// Records dropped between the previous queued record and this one.
    pub lost_before: u32,
    /// The record.
    pub record: T,
}

/// The producer's end: queues records, counts the ones that did not fit.
pub struct LossyProducer<'a, T> {
    producer: Producer<'a, Tagged<T>>,
    lost: u32,
}

impl<'a, T> LossyProducer<'a, T> {
    /// The producer over `producer`, no loss pending.
    pub fn new(producer: Producer<'a, Tagged<T>>) -> Self {
        Self { producer, lost: 0 }
    }

    /// Queues `record` with the count of records dropped since the last one queued; returns
    /// false when the queue was full (the record is dropped and counted for the next).
    pub fn push(&mut self, record: T) -> bool {
        let tagged = Tagged {
            lost_before: self.lost,
            record,
        };
        match self.producer.enqueue(tagged) {
            Ok(()) => {
                self.lost = 0;
                true
            }
            Err(_) => {
                self.lost = self.lost.saturating_add(1);
                false
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use heapless::spsc::Queue;

    /// A full queue drops the newest record; the next one that fits carries the count.
    #[test]
    fn the_next_record_carries_the_drops_before_it() {
        let mut queue: Queue<Tagged<u32>, 3> = Queue::new();
        let (producer, mut consumer) = queue.split();
        let mut p = LossyProducer::new(producer);
        assert!(p.push(1) && p.push(2));
        assert!(!p.push(3) && !p.push(4));
        let taken: [Option<Tagged<u32>>; 2] = [consumer.dequeue(), consumer.dequeue()];
        assert_eq!(
            taken.map(|t| t.map(|t| (t.lost_before, t.record))),
            [Some((0, 1)), Some((0, 2))]
        );
        assert!(p.push(5));
        assert_eq!(
            consumer.dequeue().map(|t| (t.lost_before, t.record)),
            Some((2, 5))
        );
    }
}
