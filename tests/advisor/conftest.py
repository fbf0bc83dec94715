"""A small OpenAI-compatible chat-completions server on 127.0.0.1 for the advisor's HTTP tests.

Each test scripts the replies: ``server.replies`` is a list of callables ``(request_body) ->
(status, body_dict)`` consumed one per request (the last one repeats). Every request's JSON body
and headers are kept in ``server.requests``. A reply's ``delay`` is waited on an event that the
fixture sets at teardown, so a server "sleeping" 30 s does not hold up the test's end.
"""

from __future__ import annotations

import json
import threading
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import pytest


def completion(content=None, tool_arguments=None):
    message = {"role": "assistant", "content": content}
    if tool_arguments is not None:
        message["tool_calls"] = [
            {
                "id": "call_1",
                "type": "function",
                "function": {"name": "set_lyapunov_function", "arguments": tool_arguments},
            }
        ]
    return {
        "id": "chatcmpl-1",
        "object": "chat.completion",
        "created": 0,
        "model": "fake",
        "choices": [{"index": 0, "finish_reason": "stop", "message": message}],
    }


def reply(status=200, content=None, tool_arguments=None, delay=0.0):
    def respond(body):
        if status != 200:
            return status, {"error": {"message": content or "error", "code": status}}
        return 200, completion(content, tool_arguments)

    respond.delay = delay  # waited by the handler (interruptible at teardown)
    return respond


class _Handler(BaseHTTPRequestHandler):
    def log_message(self, *args):  # keep pytest's output clean
        pass

    def do_POST(self):
        body = json.loads(self.rfile.read(int(self.headers["Content-Length"])))
        server = self.server
        server.requests.append(
            {
                "path": self.path,
                "body": body,
                "headers": {k.lower(): v for k, v in self.headers.items()},
            }
        )
        respond = server.replies.pop(0) if len(server.replies) > 1 else server.replies[0]
        server.release.wait(getattr(respond, "delay", 0.0))
        status, payload = respond(body)
        data = json.dumps(payload).encode()
        try:
            self.send_response(status)
            self.send_header("Content-Type", "application/json")
            self.send_header("Content-Length", str(len(data)))
            self.end_headers()
            self.wfile.write(data)
        except (BrokenPipeError, ConnectionResetError):  # the client timed out
            pass


@pytest.fixture
def chat_server():
    server = ThreadingHTTPServer(("127.0.0.1", 0), _Handler)
    server.daemon_threads = True
    server.requests, server.replies = [], [reply(content="{}")]
    server.release = threading.Event()  # set at teardown: ends every pending delay
    server.reply = reply  # tests script replies with chat_server.reply(...)
    thread = threading.Thread(target=server.serve_forever, args=(0.05,), daemon=True)
    thread.start()
    server.base_url = f"http://127.0.0.1:{server.server_address[1]}/v1"
    yield server
    server.release.set()
    server.shutdown()
    server.server_close()
