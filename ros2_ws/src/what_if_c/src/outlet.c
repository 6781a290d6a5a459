/*
 * _outlet: publish a message on an rcl publisher without the interpreter lock while rcl
 * sends it.
 *
 * rclpy's Publisher.publish holds the lock through rcl_publish, which hands the message
 * to each subscriber: for the Crazyflie's 63 kB Forecast and one subscriber on this
 * host, 0.49 ms at p50 and 1.7 ms at p99 in which no other thread of the predictor ran
 * Python (the executor taking the next state waited). Here the message becomes its C
 * struct under the lock, as rclpy converts it, and is sent without it.
 */

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <stdint.h>

#include "rcl/publisher.h"
#include "rcutils/error_handling.h"

#include "message_class.h"

static PyObject * outlet_publish(PyObject * module, PyObject * args)
{
  (void)module;
  unsigned long long pointer = 0;
  PyObject * message = NULL;
  if (!PyArg_ParseTuple(args, "KO", &pointer, &message)) {return NULL;}
  if (!pointer) {
    PyErr_SetString(PyExc_ValueError, "publisher must be an rcl pointer");
    return NULL;
  }
  PyObject * cls = (PyObject *)Py_TYPE(message);
  create_ros_message_t * create = capsule_function(cls, "_CREATE_ROS_MESSAGE").create;
  convert_from_py_t * from_py = capsule_function(cls, "_CONVERT_FROM_PY").from_py;
  destroy_ros_message_t * destroy = capsule_function(cls, "_DESTROY_ROS_MESSAGE").destroy;
  if (!create || !from_py || !destroy) {
    if (!PyErr_Occurred()) {
      PyErr_Format(PyExc_TypeError, "%s is not a ROS message whose support is loaded "
        "(rclpy.type_support.check_for_type_support)", Py_TYPE(message)->tp_name);
    }
    return NULL;
  }
  void * ros_message = create();
  if (!ros_message) {return PyErr_NoMemory();}
  if (!from_py(message, ros_message)) {
    destroy(ros_message);
    if (!PyErr_Occurred()) {
      PyErr_SetString(PyExc_ValueError, "the message could not be converted to C");
    }
    return NULL;
  }
  rcl_ret_t ret;
  Py_BEGIN_ALLOW_THREADS
  ret = rcl_publish((const rcl_publisher_t *)(uintptr_t)pointer, ros_message, NULL);
  Py_END_ALLOW_THREADS
  destroy(ros_message);
  if (ret != RCL_RET_OK) {
    PyErr_Format(PyExc_RuntimeError, "publishing failed: %s", rcutils_get_error_string().str);
    rcutils_reset_error();
    return NULL;
  }
  Py_RETURN_NONE;
}

static PyMethodDef OUTLET_METHODS[] = {
  {"publish", outlet_publish, METH_VARARGS,
    "publish(publisher, message): send message on the rcl publisher (a pointer), the "
    "interpreter lock released while rcl sends it."},
  {NULL, NULL, 0, NULL}
};

static struct PyModuleDef MODULE = {
  PyModuleDef_HEAD_INIT, "_outlet",
  "Publishing without the interpreter lock while rcl sends.", -1, OUTLET_METHODS,
  NULL, NULL, NULL, NULL
};

PyMODINIT_FUNC PyInit__outlet(void)
{
  return PyModule_Create(&MODULE);
}
