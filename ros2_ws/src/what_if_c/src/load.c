/*
 * _load (python -m what_if_c.load): the service soak's what-if clients, in C over rcl.
 *
 * Keeps --concurrency requests in flight from each of --clients clients of a Predict
 * service for the soak's duration, and writes what came back in the figures format of
 * the soak's Python clients (offline/benchmarks/soak.py, Load.raw()). Written in C so
 * the soak measures the node: a Python client converts every 1.65 MB answer to Python
 * objects under its own interpreter lock, and a busy answer queued behind that counts
 * against the node (docs/predictor.md, "Soak benchmark").
 *
 * It meets the soak as its Python client processes do: touches DIR/NAME.ready once
 * every client sees the service, waits for DIR/start (the seconds of load), runs,
 * waits up to --settle s for the last answers and writes DIR/NAME.json. The request is
 * read from --request, the CDR bytes of a Predict.Request (rclpy's serialize_message),
 * so the plans are made in one place, by the soak.
 *
 * Times: latencies in s of CLOCK_MONOTONIC; the stages of a busy answer in ns of
 * CLOCK_REALTIME, the clock DDS stamps samples with: (sent, written by the node,
 * received here, take begun, taken, done).
 */

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <errno.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "rcl/graph.h"
#include "rcl/rcl.h"
#include "rcutils/allocator.h"
#include "rcutils/error_handling.h"
#include "rmw/rmw.h"
#include "rmw/serialized_message.h"

#include "hybrid_predictor_interfaces/srv/predict.h"

#define FAILURE_KEY 60      /* characters of a failure's message it is counted under */
#define MAX_FAILURE_KINDS 64
#define MAX_CLIENTS 64
#define MAX_CONCURRENCY 1024
#define BUSY_PREFIX "busy"  /* hybrid_predictor.what_if_client.is_busy */

static const char USAGE[] =
  "usage: python -m what_if_c.load --service NAME --request FILE --dir DIR --name NAME\n"
  "                              --clients N --concurrency K --busy-backoff S|retry_after\n"
  "                              [--depth D] [--settle S]\n"
  "\n"
  "The service soak's what-if clients in C (offline/bench.py soak --client c).\n"
  "  --service       the Predict service, fully qualified (/vessel/predictor/predict)\n"
  "  --request       a Predict.Request as CDR bytes (rclpy serialize_message)\n"
  "  --dir, --name   where to meet the soak: NAME.ready, start, NAME.json\n"
  "  --clients       clients in this process (1-64)\n"
  "  --concurrency   requests each client keeps in flight (1-1024)\n"
  "  --busy-backoff  s a client waits after a busy answer, or retry_after: the\n"
  "                  answer's retry_after and up to a tenth more at random\n"
  "  --depth         the clients' response queue (default 1000: every client of a\n"
  "                  service is handed all of its responses, and keeps its own)\n"
  "  --settle        s to wait for the last answers after the load (default 30)\n";

typedef struct
{
  double * v;
  size_t n, cap;
} doubles_t;

typedef struct
{
  int64_t (*v)[6];
  size_t n, cap;
} stages_t;

typedef struct
{
  int64_t sequence;    /* the request's sequence number; 0: slot free */
  double sent_at;      /* s, monotonic */
  int64_t sent_ns;     /* ns, realtime */
  double resend_at;    /* s, monotonic; 0: no resend waiting */
} slot_t;

typedef struct
{
  rcl_client_t rcl;
  slot_t slots[MAX_CONCURRENCY];
} client_t;

typedef struct
{
  char key[FAILURE_KEY * 4 + 1];
  long count;
} failure_t;

typedef struct
{
  long sent, success, busy, failed;
  doubles_t latencies, success_latencies, busy_latencies;
  stages_t busy_stages;
  failure_t failures[MAX_FAILURE_KINDS];
  int failure_kinds;
  double request_kb, success_answer_kb;   /* < 0: not known */
} figures_t;

static void die(const char * what)
{
  fprintf(stderr, "what_if_c.load: error: %s\n", what);
  exit(2);
}

static void check(rcl_ret_t ret, const char * what)
{
  if (ret != RCL_RET_OK) {
    fprintf(stderr, "what_if_c.load: error: %s failed: %s\n", what, rcutils_get_error_string().str);
    exit(2);
  }
}

static double monotonic_s(void)
{
  struct timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int64_t realtime_ns(void)
{
  struct timespec t;
  clock_gettime(CLOCK_REALTIME, &t);
  return (int64_t)t.tv_sec * 1000000000LL + t.tv_nsec;
}

static void push_double(doubles_t * a, double x)
{
  if (a->n == a->cap) {
    a->cap = a->cap ? 2 * a->cap : 1024;
    a->v = realloc(a->v, a->cap * sizeof(*a->v));
    if (!a->v) {die("out of memory");}
  }
  a->v[a->n++] = x;
}

static void push_stages(stages_t * a, const int64_t row[6])
{
  if (a->n == a->cap) {
    a->cap = a->cap ? 2 * a->cap : 1024;
    a->v = realloc(a->v, a->cap * sizeof(*a->v));
    if (!a->v) {die("out of memory");}
  }
  memcpy(a->v[a->n++], row, sizeof(a->v[0]));
}

static void count_failure(figures_t * f, const char * message)
{
  char key[sizeof(f->failures[0].key)];
  /* The Python clients key by the first 60 characters; the messages are ASCII. */
  snprintf(key, sizeof(key), "%.*s", FAILURE_KEY, message);
  for (int i = 0; i < f->failure_kinds; ++i) {
    if (strcmp(f->failures[i].key, key) == 0) {
      f->failures[i].count++;
      return;
    }
  }
  if (f->failure_kinds < MAX_FAILURE_KINDS) {
    strcpy(f->failures[f->failure_kinds].key, key);
    f->failures[f->failure_kinds++].count = 1;
  }
}

static unsigned char * read_file(const char * path, size_t * size)
{
  FILE * file = fopen(path, "rb");
  if (!file) {
    fprintf(stderr, "what_if_c.load: error: cannot read %s: %s\n", path, strerror(errno));
    exit(2);
  }
  fseek(file, 0, SEEK_END);
  long length = ftell(file);
  fseek(file, 0, SEEK_SET);
  unsigned char * bytes = malloc(length > 0 ? (size_t)length : 1);
  if (!bytes || length <= 0 || fread(bytes, 1, (size_t)length, file) != (size_t)length) {
    fprintf(stderr, "what_if_c.load: error: %s is empty or unreadable\n", path);
    exit(2);
  }
  fclose(file);
  *size = (size_t)length;
  return bytes;
}

static void json_string(FILE * out, const char * s)
{
  fputc('"', out);
  for (; *s; ++s) {
    unsigned char c = (unsigned char)*s;
    if (c == '"' || c == '\\') {
      fprintf(out, "\\%c", c);
    } else if (c < 0x20) {
      fprintf(out, "\\u%04x", c);
    } else {
      fputc(c, out);
    }
  }
  fputc('"', out);
}

static void json_doubles(FILE * out, const char * name, const doubles_t * a)
{
  fprintf(out, "\"%s\": [", name);
  for (size_t i = 0; i < a->n; ++i) {
    fprintf(out, "%s%.9f", i ? ", " : "", a->v[i]);
  }
  fprintf(out, "], ");
}

static void json_kb(FILE * out, const char * name, double kb)
{
  if (kb < 0) {
    fprintf(out, "\"%s\": null", name);
  } else {
    fprintf(out, "\"%s\": %.1f", name, kb);
  }
}

/* Write the figures as Load.raw() gives them, to PATH.tmp and then PATH. */
static void write_figures(const figures_t * f, const char * path)
{
  char tmp[4200];
  snprintf(tmp, sizeof(tmp), "%s.tmp", path);
  FILE * out = fopen(tmp, "w");
  if (!out) {die("cannot write the figures");}
  fprintf(out, "{\"sent\": %ld, \"success\": %ld, \"busy\": %ld, \"failed\": %ld, ",
    f->sent, f->success, f->busy, f->failed);
  fprintf(out, "\"failures\": {");
  for (int i = 0; i < f->failure_kinds; ++i) {
    fprintf(out, "%s", i ? ", " : "");
    json_string(out, f->failures[i].key);
    fprintf(out, ": %ld", f->failures[i].count);
  }
  fprintf(out, "}, ");
  json_doubles(out, "latencies", &f->latencies);
  json_doubles(out, "success_latencies", &f->success_latencies);
  json_doubles(out, "busy_latencies", &f->busy_latencies);
  fprintf(out, "\"busy_stages\": [");
  for (size_t i = 0; i < f->busy_stages.n; ++i) {
    const int64_t * r = f->busy_stages.v[i];
    fprintf(out, "%s[%lld, %lld, %lld, %lld, %lld, %lld]", i ? ", " : "",
      (long long)r[0], (long long)r[1], (long long)r[2], (long long)r[3], (long long)r[4],
      (long long)r[5]);
  }
  fprintf(out, "], ");
  json_kb(out, "request_kb", f->request_kb);
  fprintf(out, ", ");
  json_kb(out, "success_answer_kb", f->success_answer_kb);
  fprintf(out, "}\n");
  if (fclose(out) != 0 || rename(tmp, path) != 0) {die("cannot write the figures");}
}

static const char * option(int argc, char ** argv, const char * name, const char * fallback)
{
  for (int i = 1; i + 1 < argc; i += 2) {
    if (strcmp(argv[i], name) == 0) {return argv[i + 1];}
  }
  if (!fallback) {
    fprintf(stderr, "what_if_c.load: error: %s is required\n%s", name, USAGE);
    exit(2);
  }
  return fallback;
}

static long whole(const char * text, const char * name, long low, long high)
{
  char * end = NULL;
  long value = strtol(text, &end, 10);
  if (!*text || *end || value < low || value > high) {
    fprintf(stderr, "what_if_c.load: error: %s takes an integer in [%ld, %ld], got '%s'\n",
      name, low, high, text);
    exit(2);
  }
  return value;
}

static double seconds(const char * text, const char * name)
{
  char * end = NULL;
  double value = strtod(text, &end);
  if (!*text || *end || !(value >= 0)) {
    fprintf(stderr, "what_if_c.load: error: %s takes seconds >= 0, got '%s'\n", name, text);
    exit(2);
  }
  return value;
}

typedef struct
{
  client_t * clients;
  int count, concurrency;
  const void * request;
  double deadline;
  bool follow_hint;
  double backoff;
  figures_t figures;
  long in_flight;
} load_t;

static void send_request(load_t * load, client_t * client, slot_t * slot)
{
  if (monotonic_s() >= load->deadline) {
    slot->sequence = 0;
    return;
  }
  slot->sent_at = monotonic_s();
  slot->sent_ns = realtime_ns();
  slot->resend_at = 0;
  int64_t sequence = 0;
  check(rcl_send_request(&client->rcl, load->request, &sequence), "rcl_send_request");
  slot->sequence = sequence;
  load->figures.sent++;
  load->in_flight++;
}

static void answered(
  load_t * load, client_t * client, const rmw_service_info_t * info,
  const hybrid_predictor_interfaces__srv__Predict_Response * response,
  int64_t begun, int64_t taken, const rosidl_message_type_support_t * response_type)
{
  slot_t * slot = NULL;
  for (int k = 0; k < load->concurrency; ++k) {
    if (client->slots[k].sequence == info->request_id.sequence_number) {
      slot = &client->slots[k];
      break;
    }
  }
  if (!slot) {return;}   /* not one of this client's requests in flight */
  load->in_flight--;
  double latency = monotonic_s() - slot->sent_at;
  figures_t * f = &load->figures;
  push_double(&f->latencies, latency);
  const char * message = response->message.data ? response->message.data : "";
  bool busy = !response->success && strncmp(message, BUSY_PREFIX, strlen(BUSY_PREFIX)) == 0;
  if (response->success) {
    f->success++;
    push_double(&f->success_latencies, latency);
    if (f->success_answer_kb < 0) {
      rcutils_allocator_t allocator = rcutils_get_default_allocator();
      rmw_serialized_message_t bytes = rmw_get_zero_initialized_serialized_message();
      if (rmw_serialized_message_init(&bytes, 0, &allocator) == RMW_RET_OK &&
        rmw_serialize(response, response_type, &bytes) == RMW_RET_OK)
      {
        f->success_answer_kb = (double)bytes.buffer_length / 1e3;
      }
      rmw_serialized_message_fini(&bytes);
    }
  } else if (busy) {
    f->busy++;
    push_double(&f->busy_latencies, latency);
    int64_t row[6] = {slot->sent_ns, info->source_timestamp, info->received_timestamp,
      begun, taken, realtime_ns()};
    push_stages(&f->busy_stages, row);
  } else {
    f->failed++;
    count_failure(f, message);
  }
  slot->sequence = 0;
  if (monotonic_s() >= load->deadline) {return;}
  double wait = 0.0;
  if (busy) {
    wait = load->follow_hint ?
      response->retry_after * (1.0 + 0.1 * ((double)rand() / RAND_MAX)) : load->backoff;
  }
  if (wait > 0) {
    slot->resend_at = monotonic_s() + wait;
  } else {
    send_request(load, client, slot);
  }
}

/* Send the requests whose back-off has passed; return s until the next one is due. */
static double resend_due(load_t * load)
{
  double now = monotonic_s(), next = 1.0;
  for (int i = 0; i < load->count; ++i) {
    for (int k = 0; k < load->concurrency; ++k) {
      slot_t * slot = &load->clients[i].slots[k];
      if (slot->resend_at <= 0) {continue;}
      if (now >= load->deadline) {
        slot->resend_at = 0;   /* the load is over: its request is not sent */
      } else if (slot->resend_at <= now) {
        send_request(load, &load->clients[i], slot);
      } else if (slot->resend_at - now < next) {
        next = slot->resend_at - now;
      }
    }
  }
  return next;
}

static int run(int argc, char ** argv)
{
  for (int i = 1; i < argc; ++i) {
    if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
      fputs(USAGE, stdout);
      return 0;
    }
  }
  if (argc % 2 == 0) {
    fprintf(stderr, "what_if_c.load: error: options come in pairs\n%s", USAGE);
    return 2;
  }
  const char * service = option(argc, argv, "--service", NULL);
  const char * request_path = option(argc, argv, "--request", NULL);
  const char * dir = option(argc, argv, "--dir", NULL);
  const char * name = option(argc, argv, "--name", NULL);
  int clients = (int)whole(option(argc, argv, "--clients", NULL), "--clients", 1, MAX_CLIENTS);
  int concurrency = (int)whole(option(argc, argv, "--concurrency", NULL), "--concurrency", 1,
    MAX_CONCURRENCY);
  const char * backoff = option(argc, argv, "--busy-backoff", NULL);
  long depth = whole(option(argc, argv, "--depth", "1000"), "--depth", 1, 1000000);
  double settle = seconds(option(argc, argv, "--settle", "30"), "--settle");

  load_t load = {0};
  load.concurrency = concurrency;
  load.follow_hint = strcmp(backoff, "retry_after") == 0;
  load.backoff = load.follow_hint ? 0.0 : seconds(backoff, "--busy-backoff");
  load.figures.success_answer_kb = -1;

  const rosidl_message_type_support_t * request_type = ROSIDL_GET_MSG_TYPE_SUPPORT(
    hybrid_predictor_interfaces, srv, Predict_Request);
  const rosidl_message_type_support_t * response_type = ROSIDL_GET_MSG_TYPE_SUPPORT(
    hybrid_predictor_interfaces, srv, Predict_Response);
  const rosidl_service_type_support_t * service_type = ROSIDL_GET_SRV_TYPE_SUPPORT(
    hybrid_predictor_interfaces, srv, Predict);

  rcl_allocator_t allocator = rcl_get_default_allocator();
  rcl_init_options_t init_options = rcl_get_zero_initialized_init_options();
  check(rcl_init_options_init(&init_options, allocator), "rcl_init_options_init");
  rcl_context_t context = rcl_get_zero_initialized_context();
  check(rcl_init(0, NULL, &init_options, &context), "rcl_init");
  rcl_node_t node = rcl_get_zero_initialized_node();
  rcl_node_options_t node_options = rcl_node_get_default_options();
  char node_name[256];
  snprintf(node_name, sizeof(node_name), "soak_%s", name);
  check(rcl_node_init(&node, node_name, "", &context, &node_options), "rcl_node_init");

  hybrid_predictor_interfaces__srv__Predict_Request request;
  hybrid_predictor_interfaces__srv__Predict_Request__init(&request);
  size_t size = 0;
  unsigned char * bytes = read_file(request_path, &size);
  rmw_serialized_message_t serialized = rmw_get_zero_initialized_serialized_message();
  serialized.buffer = bytes;
  serialized.buffer_length = size;
  serialized.buffer_capacity = size;
  if (rmw_deserialize(&serialized, request_type, &request) != RMW_RET_OK) {
    fprintf(stderr, "what_if_c.load: error: %s is not a Predict.Request\n", request_path);
    return 2;
  }
  free(bytes);
  load.request = &request;
  load.figures.request_kb = (double)size / 1e3;

  load.clients = calloc((size_t)clients, sizeof(client_t));
  if (!load.clients) {die("out of memory");}
  load.count = clients;
  rcl_client_options_t client_options = rcl_client_get_default_options();
  client_options.qos.history = RMW_QOS_POLICY_HISTORY_KEEP_LAST;
  client_options.qos.depth = (size_t)depth;
  for (int i = 0; i < clients; ++i) {
    load.clients[i].rcl = rcl_get_zero_initialized_client();
    check(rcl_client_init(&load.clients[i].rcl, &node, service_type, service,
      &client_options), "rcl_client_init");
  }
  double ready_by = monotonic_s() + 30.0;
  for (int i = 0; i < clients; ++i) {
    bool available = false;
    while (check(rcl_service_server_is_available(&node, &load.clients[i].rcl, &available),
      "rcl_service_server_is_available"), !available)
    {
      if (monotonic_s() > ready_by) {
        fprintf(stderr, "what_if_c.load: error: no %s within 30 s\n", service);
        return 2;
      }
      usleep(10000);
    }
  }
  char path[4096];
  snprintf(path, sizeof(path), "%s/%s.ready", dir, name);
  FILE * ready = fopen(path, "w");
  if (!ready) {die("cannot write the ready mark");}
  fclose(ready);
  snprintf(path, sizeof(path), "%s/start", dir);
  FILE * start = NULL;
  while (!(start = fopen(path, "r"))) {usleep(10000);}
  double load_s = 0;
  if (fscanf(start, "%lf", &load_s) != 1 || !(load_s >= 0)) {die("the start mark holds no seconds");}
  fclose(start);

  rcl_wait_set_t wait_set = rcl_get_zero_initialized_wait_set();
  check(rcl_wait_set_init(&wait_set, 0, 0, 0, (size_t)clients, 0, 0, &context, allocator),
    "rcl_wait_set_init");
  hybrid_predictor_interfaces__srv__Predict_Response response;
  hybrid_predictor_interfaces__srv__Predict_Response__init(&response);
  srand((unsigned)getpid());
  load.deadline = monotonic_s() + load_s;
  for (int i = 0; i < clients; ++i) {
    for (int k = 0; k < concurrency; ++k) {
      send_request(&load, &load.clients[i], &load.clients[i].slots[k]);
    }
  }
  double give_up = load.deadline + settle;
  while (monotonic_s() < give_up) {
    double next = resend_due(&load);
    /* After the deadline no back-off ends in a request: the load is done when the
       requests in flight are answered. */
    if (monotonic_s() >= load.deadline && load.in_flight == 0) {break;}
    check(rcl_wait_set_clear(&wait_set), "rcl_wait_set_clear");
    for (int i = 0; i < clients; ++i) {
      check(rcl_wait_set_add_client(&wait_set, &load.clients[i].rcl, NULL),
        "rcl_wait_set_add_client");
    }
    rcl_ret_t waited = rcl_wait(&wait_set, (int64_t)(next * 1e9));
    if (waited == RCL_RET_TIMEOUT) {continue;}
    check(waited, "rcl_wait");
    for (int i = 0; i < clients; ++i) {
      if (!wait_set.clients[i]) {continue;}
      for (;;) {
        rmw_service_info_t info;
        int64_t begun = realtime_ns();
        rcl_ret_t took = rcl_take_response_with_info(&load.clients[i].rcl, &info, &response);
        if (took == RCL_RET_CLIENT_TAKE_FAILED) {break;}
        check(took, "rcl_take_response_with_info");
        answered(&load, &load.clients[i], &info, &response, begun, realtime_ns(),
          response_type);
      }
    }
  }
  snprintf(path, sizeof(path), "%s/%s.json", dir, name);
  write_figures(&load.figures, path);

  hybrid_predictor_interfaces__srv__Predict_Response__fini(&response);
  hybrid_predictor_interfaces__srv__Predict_Request__fini(&request);
  check(rcl_wait_set_fini(&wait_set), "rcl_wait_set_fini");
  for (int i = 0; i < clients; ++i) {
    check(rcl_client_fini(&load.clients[i].rcl, &node), "rcl_client_fini");
  }
  check(rcl_node_fini(&node), "rcl_node_fini");
  check(rcl_shutdown(&context), "rcl_shutdown");
  check(rcl_context_fini(&context), "rcl_context_fini");
  check(rcl_init_options_fini(&init_options), "rcl_init_options_fini");
  return 0;
}

/* run(argv): the load as the command line asks, the interpreter's lock released
   throughout (nothing of the load is Python's); returns the exit status. */
static PyObject * py_run(PyObject * self, PyObject * args)
{
  (void)self;
  PyObject * list = NULL;
  if (!PyArg_ParseTuple(args, "O!", &PyList_Type, &list)) {return NULL;}
  Py_ssize_t count = PyList_Size(list);
  char ** argv = calloc((size_t)count + 1, sizeof(char *));
  if (!argv) {return PyErr_NoMemory();}
  for (Py_ssize_t i = 0; i < count; ++i) {
    const char * text = PyUnicode_AsUTF8(PyList_GetItem(list, i));
    if (!text || !(argv[i] = strdup(text))) {
      for (Py_ssize_t k = 0; k < i; ++k) {free(argv[k]);}
      free(argv);
      return text ? PyErr_NoMemory() : NULL;
    }
  }
  int status;
  Py_BEGIN_ALLOW_THREADS
  status = run((int)count, argv);
  Py_END_ALLOW_THREADS
  for (Py_ssize_t i = 0; i < count; ++i) {free(argv[i]);}
  free(argv);
  return PyLong_FromLong(status);
}

static PyMethodDef METHODS[] = {
  {"run", py_run, METH_VARARGS,
    "run(argv) -> int: the load as the command line argv (argv[0] the program) asks."},
  {NULL, NULL, 0, NULL}
};

static struct PyModuleDef MODULE = {
  PyModuleDef_HEAD_INIT, "_load", "The soak's what-if clients in C (see run).", -1, METHODS,
  NULL, NULL, NULL, NULL
};

PyMODINIT_FUNC PyInit__load(void)
{
  return PyModule_Create(&MODULE);
}
