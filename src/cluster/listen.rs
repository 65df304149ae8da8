//! The one subscription of a replica: postings and control messages from every replica, handed
//! out through a broadcast channel; reconnects by itself.

use super::keys::{CONTROL, DROPPED, EVENTS};
use super::link::Inner;
use crate::jobs::peers::{Control, Message, Shelf};
use futures_util::StreamExt;
use std::sync::Weak;
use std::time::Duration;

/// The payload of a posting on `meshfit:events`: the id, a space, the posting's JSON.
pub(super) fn event(id: &str, json: &str) -> String {
    format!("{id} {json}")
}

/// The payload of a control message.
pub(super) fn control(id: &str, what: Control) -> String {
    let verb = match what {
        Control::Cancel => "cancel",
        Control::Detach => "detach",
    };
    format!("{verb} {id}")
}

/// The payload of a dropped file: its shelf, a space, its id.
pub(super) fn dropped(shelf: Shelf, id: &str) -> String {
    format!("{} {id}", shelf.name())
}

fn parse(channel: &str, payload: &str) -> Option<Message> {
    let (head, rest) = payload.split_once(' ')?;
    match channel {
        EVENTS => Some(Message::Posted(head.to_owned(), Box::new(serde_json::from_str(rest).ok()?))),
        CONTROL => {
            let what = match head {
                "cancel" => Control::Cancel,
                "detach" => Control::Detach,
                _ => return None,
            };
            Some(Message::Control(rest.to_owned(), what))
        }
        DROPPED => Some(Message::Dropped(Shelf::named(head)?, rest.to_owned())),
        _ => None,
    }
}

/// Subscribes, forwards messages until the connection drops, and starts again, until the
/// replica's cluster handle is gone.
pub(super) async fn run(client: redis::Client, inner: Weak<Inner>) {
    let mut delay = Duration::from_millis(100);
    loop {
        let subscribed = async {
            let mut pubsub = client.get_async_pubsub().await?;
            pubsub.subscribe(&[EVENTS, CONTROL, DROPPED]).await?;
            Ok::<_, redis::RedisError>(pubsub)
        };
        let attempt = tokio::time::timeout(Duration::from_secs(2), subscribed).await;
        let Some(inner) = inner.upgrade() else { return };
        match attempt {
            Ok(Ok(pubsub)) => {
                delay = Duration::from_millis(100);
                // Subscribed: Redis answers (messages missed meanwhile are read back at the
                // next sweep).
                let _ = inner.note(Ok(()));
                let messages = inner.messages.clone();
                drop(inner);
                let mut stream = pubsub.into_on_message();
                while let Some(msg) = stream.next().await {
                    let Ok(payload) = msg.get_payload::<String>() else { continue };
                    if let Some(message) = parse(msg.get_channel_name(), &payload) {
                        // No receiver is fine: no job is followed right now.
                        let _ = messages.send(message);
                    }
                }
            }
            Ok(Err(e)) => drop(inner.note::<()>(Err(e))),
            Err(_) => drop(inner.unreachable(std::io::Error::from(std::io::ErrorKind::TimedOut).into())),
        }
        tokio::time::sleep(delay).await;
        delay = (delay * 2).min(Duration::from_secs(2));
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::jobs::peers::Posting;

    #[test]
    fn messages_read_back_as_sent_and_anything_else_is_ignored() {
        let posting = Posting {
            status: "running".into(),
            seq: 7,
            progress: None,
            stats: None,
            failure: None,
            elapsed_ms: None,
            run: "a#0".into(),
        };
        let json = serde_json::to_string(&posting).unwrap();
        let Some(Message::Posted(id, got)) = parse(EVENTS, &event("abc", &json)) else { panic!() };
        assert_eq!((id.as_str(), *got), ("abc", posting));
        for what in [Control::Cancel, Control::Detach] {
            let Some(Message::Control(id, got)) = parse(CONTROL, &control("abc", what)) else { panic!() };
            assert_eq!((id.as_str(), got), ("abc", what));
        }
        for shelf in [Shelf::Dataset, Shelf::Tile] {
            let Some(Message::Dropped(got, id)) = parse(DROPPED, &dropped(shelf, "abc")) else { panic!() };
            assert_eq!((got, id.as_str()), (shelf, "abc"));
        }
        assert!(parse(DROPPED, "shelf abc").is_none());
        assert!(parse(CONTROL, "explode abc").is_none());
        assert!(parse(EVENTS, "abc {not json").is_none());
        assert!(parse("other", &control("abc", Control::Cancel)).is_none());
    }
}
