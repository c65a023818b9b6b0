//! A response body that keeps its request's in-flight permit until the body has been sent.
//!
//! A finished scene is as large as the upload, and a client that reads its answer slowly would
//! otherwise keep it in memory after its job has left the pool, unaccounted: under overload
//! with slow readers, answers pile up without bound. The body is handed to hyper in 256 KiB
//! frames, and hyper asks for the next frame only once its write buffer has room, so the body
//! (and with it the permit) lives until the answer is nearly all on the wire.

use axum::body::Bytes;
use http_body::{Body, Frame, SizeHint};
use std::collections::VecDeque;
use std::convert::Infallible;
use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use tokio::sync::OwnedSemaphorePermit;

const FRAME: usize = 256 << 10;

pub struct HeldBody {
    /// What is left to send, piece by piece (a scene written in pieces is sent as it lies:
    /// slices of the upload and the new data, never put together in one buffer).
    rest: VecDeque<Bytes>,
    len: usize,
    permit: Option<OwnedSemaphorePermit>,
}

impl HeldBody {
    pub fn new(bytes: impl Into<Bytes>, permit: OwnedSemaphorePermit) -> Self {
        HeldBody::from_parts(vec![bytes.into()], permit)
    }

    /// A body of these parts, in order.
    pub fn from_parts(parts: Vec<Bytes>, permit: OwnedSemaphorePermit) -> Self {
        let rest: VecDeque<Bytes> = parts.into_iter().filter(|p| !p.is_empty()).collect();
        HeldBody {
            len: rest.iter().map(Bytes::len).sum(),
            rest,
            permit: Some(permit),
        }
    }
}

impl Body for HeldBody {
    type Data = Bytes;
    type Error = Infallible;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        _: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, Infallible>>> {
        let Some(front) = self.rest.front_mut() else {
            self.permit = None;
            return Poll::Ready(None);
        };
        let n = front.len().min(FRAME);
        let frame = front.split_to(n);
        if front.is_empty() {
            self.rest.pop_front();
        }
        self.len -= frame.len();
        Poll::Ready(Some(Ok(Frame::data(frame))))
    }

    fn is_end_stream(&self) -> bool {
        self.rest.is_empty()
    }

    fn size_hint(&self) -> SizeHint {
        SizeHint::with_exact(self.len as u64)
    }
}

/// A short body that, once sent, keeps its response open for a while before it ends: hyper
/// closes a connection whose request body is unread as soon as the response ends, and a close
/// with unread bytes is a reset that can overtake the response at the client. With
/// `Content-Length` the client has its whole answer before the wait.
pub struct LingeringBody {
    rest: Bytes,
    linger: Option<Pin<Box<tokio::time::Sleep>>>,
    duration: std::time::Duration,
}

impl LingeringBody {
    /// `body` must be small and already in memory (a problem document); anything else is sent
    /// as nothing.
    pub fn new(body: axum::body::Body, duration: std::time::Duration) -> Self {
        let rest = match body.size_hint().exact() {
            Some(n) if n <= 64 << 10 => {
                futures_util::FutureExt::now_or_never(http_body_util::BodyExt::collect(body))
                    .and_then(Result::ok)
                    .map(|collected| collected.to_bytes())
                    .unwrap_or_default()
            }
            _ => Bytes::new(),
        };
        LingeringBody {
            rest,
            linger: None,
            duration,
        }
    }
}

impl Body for LingeringBody {
    type Data = Bytes;
    type Error = Infallible;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, Infallible>>> {
        if !self.rest.is_empty() {
            let frame = std::mem::take(&mut self.rest);
            return Poll::Ready(Some(Ok(Frame::data(frame))));
        }
        let duration = self.duration;
        let linger = self
            .linger
            .get_or_insert_with(|| Box::pin(tokio::time::sleep(duration)));
        linger.as_mut().poll(cx).map(|()| None)
    }

    fn size_hint(&self) -> SizeHint {
        SizeHint::with_exact(self.rest.len() as u64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use http_body_util::BodyExt;
    use std::sync::Arc;
    use tokio::sync::Semaphore;

    #[tokio::test]
    async fn sends_everything_in_frames_then_frees_the_permit() {
        let permits = Arc::new(Semaphore::new(1));
        let data: Vec<u8> = (0..(FRAME * 2 + 5)).map(|i| i as u8).collect();
        let mut body = HeldBody::new(data.clone(), permits.clone().try_acquire_owned().unwrap());
        assert_eq!(body.size_hint().exact(), Some(data.len() as u64));
        let mut sent = Vec::new();
        let mut frames = 0;
        while let Some(frame) = body.frame().await {
            assert_eq!(permits.available_permits(), 0, "held while sending");
            sent.extend_from_slice(&frame.unwrap().into_data().unwrap());
            frames += 1;
        }
        assert_eq!((sent, frames), (data, 3));
        assert_eq!(permits.available_permits(), 1);
    }

    #[tokio::test]
    async fn parts_are_sent_in_order_in_frames() {
        let permits = Arc::new(Semaphore::new(1));
        let first: Vec<u8> = (0..(FRAME + 3)).map(|i| i as u8).collect();
        let parts = vec![
            Bytes::from(first.clone()),
            Bytes::new(),
            Bytes::from_static(b"tail"),
        ];
        let mut body = HeldBody::from_parts(parts, permits.clone().try_acquire_owned().unwrap());
        let total = first.len() + 4;
        assert_eq!(body.size_hint().exact(), Some(total as u64));
        let mut sent = Vec::new();
        while let Some(frame) = body.frame().await {
            sent.extend_from_slice(&frame.unwrap().into_data().unwrap());
            assert_eq!(body.size_hint().exact(), Some((total - sent.len()) as u64));
        }
        let mut expected = first;
        expected.extend_from_slice(b"tail");
        assert_eq!(sent, expected);
        assert_eq!(permits.available_permits(), 1);
    }

    #[tokio::test]
    async fn a_body_dropped_unsent_frees_the_permit() {
        let permits = Arc::new(Semaphore::new(1));
        let body = HeldBody::new(vec![0u8; 10], permits.clone().try_acquire_owned().unwrap());
        drop(body);
        assert_eq!(permits.available_permits(), 1);
    }
}
