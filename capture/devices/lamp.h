// The Lamp interface: the lamp on its relay.
#pragma once

#include <string>

#include "config/config.h"
#include "config/result.h"

namespace rig {

class Lamp {
 public:
  virtual ~Lamp() = default;
  virtual std::string Describe() const = 0;
  virtual Status Open() = 0;
  // Switches on and waits out the warm-up time before returning.
  virtual Status On() = 0;
  virtual Status Off() = 0;
  // Switches off and releases the line; called on exit, on fault and on Ctrl-C.
  virtual void Close() = 0;
};

}  // namespace rig
