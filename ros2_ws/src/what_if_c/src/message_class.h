/*
 * A message class's C functions, as rclpy finds them: capsules on the class's metaclass
 * (rosidl_generator_py), loaded once rclpy.type_support.check_for_type_support(cls) ran.
 */

#ifndef WHAT_IF_C__MESSAGE_CLASS_H_
#define WHAT_IF_C__MESSAGE_CLASS_H_

#include <Python.h>

#include <stdbool.h>

typedef bool convert_from_py_t(PyObject *, void *);
typedef PyObject * convert_to_py_t(void *);
typedef void * create_ros_message_t(void);
typedef void destroy_ros_message_t(void *);

typedef union
{
  void * pointer;
  convert_to_py_t * to_py;
  convert_from_py_t * from_py;
  create_ros_message_t * create;
  destroy_ros_message_t * destroy;
} function_t;

/* The function NAME (e.g. "_CONVERT_FROM_PY") of message class CLS; NULL when its support
   is not loaded, with a Python error set if the attribute itself was missing. */
static inline function_t capsule_function(PyObject * cls, const char * name)
{
  function_t function = {NULL};
  PyObject * capsule = PyObject_GetAttrString((PyObject *)Py_TYPE(cls), name);
  if (capsule) {
    function.pointer = capsule == Py_None ? NULL : PyCapsule_GetPointer(capsule, NULL);
    Py_DECREF(capsule);
  }
  return function;
}

#endif  /* WHAT_IF_C__MESSAGE_CLASS_H_ */
