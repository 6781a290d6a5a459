/*
 * An rcl call's failure as a Python RuntimeError naming what failed, rcl's error reset.
 */

#ifndef WHAT_IF_C__RCL_CHECK_H_
#define WHAT_IF_C__RCL_CHECK_H_

#include <Python.h>

#include <stdbool.h>

#include "rcl/types.h"
#include "rcutils/error_handling.h"

/* True if RET is RCL_RET_OK; else false, with "WHAT failed: rcl's reason" raised. */
static inline bool check_rcl(rcl_ret_t ret, const char * what)
{
  if (ret == RCL_RET_OK) {return true;}
  PyErr_Format(PyExc_RuntimeError, "%s failed: %s", what, rcutils_get_error_string().str);
  rcutils_reset_error();
  return false;
}

#endif  /* WHAT_IF_C__RCL_CHECK_H_ */
