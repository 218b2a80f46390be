# arduino-mk settings for esoarm_rig.ino (called by firmware/Makefile from the sketch folder).
BOARD_TAG = uno
ARDUINO_DIR ?= /usr/share/arduino
ARDMK_DIR ?= /usr/share/arduino
TARGET = esoarm_rig
ARDUINO_QUIET = 1
# Debian's gcc-avr 5.4 defines DECIMAL_DIG in <float.h> for C99 only; the core's WString.cpp
# needs it in C++ too.
CXXFLAGS += -DDECIMAL_DIG=__DECIMAL_DIG__

SKETCH_DEFINES := $(if $(filter bts7960,$(ESOARM_DRIVER)),-DESOARM_DRIVER_BTS7960) \
  $(if $(SAMPLE_PERIOD_US),-DSAMPLE_PERIOD_US=$(SAMPLE_PERIOD_US)UL) \
  $(if $(ENCODER_PPR),-DENCODER_PPR=$(ENCODER_PPR)UL) \
  $(if $(BAUD),-DBAUD=$(BAUD)UL) \
  $(if $(STREAM_EVERY),-DSTREAM_EVERY=$(STREAM_EVERY)u) \
  $(if $(STREAM_POLLED),-DESOARM_STREAM_POLLED) \
  $(if $(ONBOARD),-DESOARM_ONBOARD -I$(abspath $(ONBOARD)))

include $(ARDMK_DIR)/Arduino.mk

# The sketch (not the core) compiles with every warning as an error.
$(OBJDIR)/esoarm_rig.ino.o: CPPFLAGS += -Wextra -Werror $(SKETCH_DEFINES)

# On-board mode: the generated controller (esoarm codegen ... --target avr --out DIR) is
# compiled into the sketch; it is rebuilt when the generated files change.
ifneq ($(ONBOARD),)
$(OBJDIR)/esoarm_rig.ino.o: $(abspath $(ONBOARD))/esoarm_controller.c \
  $(abspath $(ONBOARD))/esoarm_controller.h $(abspath $(ONBOARD))/esoarm_reference.c \
  $(abspath $(ONBOARD))/esoarm_reference.h
endif

# The settings are part of the build: the file changes (and the sketch is rebuilt) only when
# SAMPLE_PERIOD_US, ENCODER_PPR, BAUD, STREAM_EVERY, STREAM_POLLED or
# the driver differ from the last build in OBJDIR.
SETTINGS := $(OBJDIR)/settings.txt
$(OBJDIR)/esoarm_rig.ino.o: $(SETTINGS)
.PHONY: settings-check
$(SETTINGS): settings-check
	@mkdir -p $(dir $@)
	@echo '$(strip $(SKETCH_DEFINES))' | cmp -s - $@ || echo '$(strip $(SKETCH_DEFINES))' > $@

.PHONY: build-and-size
build-and-size: $(TARGET_HEX)
	@flash=$$($(SIZE) -A $(TARGET_ELF) | awk '/^\.text|^\.data/ {s += $$2} END {print s}'); \
	ram=$$($(SIZE) -A $(TARGET_ELF) | awk '/^\.data|^\.bss/ {s += $$2} END {print s}'); \
	echo "$(TARGET_ELF): flash $$flash of 32256 bytes, RAM $$ram of 2048 bytes (static)"
